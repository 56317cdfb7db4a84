"""Typed results that travel as JSON: a stage's result written to a ledger or a report file and read back checked.

A result is a frozen dataclass that also derives from ``JsonRecord``; pydantic's ``TypeAdapter`` turns it into
JSON-ready data (paths as text, tuples as lists, nested results as objects) and validates such data back into it,
field by field, so a file of another shape is refused rather than half read.
"""
from __future__ import annotations

from functools import cache
from typing import Any, Self

from pydantic import TypeAdapter, ValidationError


class JsonRecord:
    """Mixin for a frozen dataclass: ``to_json`` and ``from_json`` through its own field types."""

    def to_json(self) -> dict[str, Any]:
        """The result as JSON-ready data."""
        return _adapter(type(self)).dump_python(self, mode="json")

    @classmethod
    def from_json(cls, data: Any) -> Self:
        """The result from ``to_json``'s data; ``RecordMismatch`` names the fields that do not fit."""
        try:
            return _adapter(cls).validate_python(data)
        except ValidationError as exc:
            fields = ", ".join(".".join(str(part) for part in error["loc"]) or "(whole)" for error in exc.errors())
            raise RecordMismatch(f"a stored {cls.__name__} does not fit its fields ({fields})") from exc


class RecordMismatch(ValueError):
    """Stored data that is not the record it was read as (written by another version, or edited)."""


@cache
def _adapter(cls: type) -> TypeAdapter:
    return TypeAdapter(cls)
