"""Resumable stages: each stage's inputs are hashed; a stage that finished with the same inputs is skipped.

The ledger (``stages.json`` in the run folder) records per stage its key, status, time taken and its result (a
``JsonRecord``), which a skipped stage hands back as the same type. A failed stage is recorded with its error and stops
the run; everything before it stays.
"""
from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from detector.formats import read_record, write_record
from detector.datasets.model import BAD_INPUT_ERRORS
from detector.records import JsonRecord, RecordMismatch

Result = TypeVar("Result", bound=JsonRecord)


class StageFailed(RuntimeError):
    """A stage raised; the message names it and the cause."""


@dataclass
class StageRecord:
    name: str
    key: str
    status: str
    seconds: float
    summary: dict[str, Any] = field(default_factory=dict)
    error: str = ""
    ran: bool = True


def late_note(job: str, minutes: float, total_s: float, stages: list[tuple[str, float, float]]) -> str | None:
    """When a job given ``minutes`` took ``total_s``, more: by how much, and the (at most two) ``stages`` (name,
    seconds taken, seconds planned) that ran furthest past their plan, in one line for the terminal; None when it
    kept to its minutes. Every command with ``--minutes`` says it in these words."""
    if total_s <= 60 * minutes:
        return None
    late = sorted(((taken - planned, name, taken, planned) for name, taken, planned in stages), reverse=True)
    reasons = ", ".join(f"{name} took {taken:.0f} s where {planned:.0f} were planned"
                        for excess, name, taken, planned in late[:2] if excess > 0)
    return (f"{job} took {total_s / 60:.1f} minutes of the {minutes:g} asked for ({total_s / 60 - minutes:+.1f}): "
            f"{reasons or 'no stage ran past its plan'} - a busy machine slows every stage; give more --minutes, "
            "or run it when the machine is quiet")


def stage_key(**inputs: Any) -> str:
    """Stable hash of a stage's inputs (settings, and the keys of the stages it reads from)."""
    text = json.dumps(inputs, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_fingerprint(path: Path | None) -> str:
    """Hash of a file's bytes, so a stage that reads it reruns when it changes (``"none"`` for no file)."""
    if path is None:
        return "none"
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


class StageLedger:
    """Runs stages in order, skipping those already done with the same key."""

    #: The ledger's file in the run's folder.
    FILE_NAME = "stages.json"

    def __init__(self, folder: Path, announce: Callable[[str], None] = print):
        self.folder = Path(folder)
        self.path = self.folder / self.FILE_NAME
        self.announce = announce
        self.records: dict[str, StageRecord] = {}
        if self.path.is_file():
            self.records = self._read()
        self.order: list[str] = []

    def _read(self) -> dict[str, StageRecord]:
        """The ledger's records; one ValueError for any damage, saying what to do with the run folder."""
        fix = (f"the run folder {self.folder} cannot be resumed - remove it to start the run again, or give --out a "
               "new folder")
        try:
            entries = read_record(self.path, "stages")
        except ValueError as error:
            raise ValueError(f"{str(error).split(' - ')[0]}; {fix}") from None
        records = {}
        for name, data in entries.items():
            try:
                records[name] = StageRecord(**{**data, "ran": False})
            except TypeError:  # not a mapping, a field missing or one too many
                raise ValueError(f"{self.path}: the stage {name!r} is not a record this release wrote; {fix}") from None
        return records

    @classmethod
    def check_folder(cls, out: Path, command: str) -> None:
        """Refuse an ``out`` that is a file or a folder holding files of its own: a resumable run writes, and on a
        rerun replaces, folders inside it. A new or empty folder starts a run of ``command``; an earlier run's (with
        its ledger) resumes."""
        if out.is_dir() and (out / cls.FILE_NAME).is_file():
            return
        entries = sorted(entry.name for entry in out.iterdir()) if out.is_dir() else []
        if out.exists() and (not out.is_dir() or entries):
            held = f"holds {', '.join(entries[:3])}{' ...' if len(entries) > 3 else ''}" if entries else "is a file"
            raise ValueError(f"--out {out} {held}, not an earlier {command}'s - give a new or empty folder (or an "
                             f"earlier {command}'s to resume it); nothing was written")

    def previous(self, name: str) -> StageRecord | None:
        return self.records.get(name)

    def run(self, name: str, key: str, outputs: list[Path], work: Callable[[], Result],
            result: type[Result]) -> Result:
        """Run ``work`` unless stage ``name`` is recorded done with ``key``, its outputs exist and its recorded
        result reads back as a ``result``; returns the stage's result."""
        self.order.append(name)
        kept = self._kept_result(name, key, outputs, result)
        if kept is not None:
            return kept
        self.announce(f"[{len(self.order)}] {name} ...")
        start = time.perf_counter()
        try:
            produced = work()
        except Exception as exc:
            self.records[name] = StageRecord(name, key, "failed", time.perf_counter() - start,
                                             error=f"{type(exc).__name__}: {exc}")
            self._save()
            cause = str(exc) if isinstance(exc, BAD_INPUT_ERRORS) else f"{type(exc).__name__}: {exc}"
            kept_any = any(record.status == "done" for record in self.records.values())
            then = (f"Earlier stages are kept in {self.folder}; fix the cause and run again to resume." if kept_any
                    else "Fix the cause and run the command again.")
            raise StageFailed(f"stage {name!r} failed: {cause}\n{then}") from exc
        self.records[name] = StageRecord(name, key, "done", time.perf_counter() - start, produced.to_json())
        self._save()
        return produced

    def _kept_result(self, name: str, key: str, outputs: list[Path], result: type[Result]) -> Result | None:
        """The recorded result of a stage done with ``key`` whose outputs exist; None when it must run."""
        record = self.records.get(name)
        if not (record and record.status == "done" and record.key == key and all(Path(p).exists() for p in outputs)):
            return None
        try:
            kept = result.from_json(record.summary)
        except RecordMismatch as exc:
            self.announce(f"[{len(self.order)}] {name}: {exc}, run again")
            return None
        record.ran = False
        self.announce(f"[{len(self.order)}] {name}: up to date, skipped (took {record.seconds:.0f} s before)")
        return kept

    def _save(self) -> None:
        data = {name: {k: v for k, v in asdict(r).items() if k != "ran"} for name, r in self.records.items()}
        write_record(self.path, "stages", data)

    def timings(self) -> list[StageRecord]:
        """Records of this run's stages, in order."""
        return [self.records[name] for name in self.order if name in self.records]
