"""Map the class names a dataset uses onto the canonical landmark codes (by name, never by index).

Every command reads class names through ``class_codes``, so every command accepts and refuses the same names in
the same words.
"""
from __future__ import annotations

import re
from pathlib import Path

from detector.datasets.model import Problem
from naoslam.landmarks import CLASSES

_COLOUR_LETTER = {"pink": "p", "magenta": "p", "blue": "b", "skyblue": "b", "cyan": "b", "yellow": "y", "green": "g"}


def canonical_class(name: str) -> str | None:
    """The canonical code for a dataset's class name, or None when it names no landmark.

    Accepts the codes themselves in any case (``"BP"``), with separators (``"b-p"``), beside other words
    (``"pole_bp"``, ``"BP pole"``), and colour words top band first (``"blue-pink"``, ``"Blue over Pink"``,
    ``"sky blue / pink"``).
    """
    text = str(name).strip().lower()
    compact = re.sub(r"[^a-z]", "", text)
    if compact in CLASSES:
        return compact
    words = re.findall(r"[a-z]+", text.replace("sky blue", "skyblue"))
    letters = [_COLOUR_LETTER[w] for w in words if w in _COLOUR_LETTER]
    if letters:
        code = "".join(letters)
        return code if code in CLASSES else None
    codes = [w for w in words if w in CLASSES]
    return codes[0] if len(codes) == 1 else None


def parse_renames(pairs: list[str] | None) -> dict[str, str]:
    """``["pink-blue=pb", ...]`` from ``--rename`` as a dict; a pair that is not OLD=CODE raises ValueError."""
    renames = {}
    for pair in pairs or []:
        old, sep, new = pair.partition("=")
        if not sep or not old.strip() or new.strip() not in CLASSES:
            raise ValueError(f"--rename {pair!r}: write OLD=NEW with NEW one of {' '.join(CLASSES)}, e.g. 'pink-blue=pb'")
        renames[old.strip()] = new.strip()
    return renames


def class_codes(raw_names: list, source: Path, renames: dict[str, str] | None = None) -> tuple[tuple[str | None, ...], list[Problem]]:
    """The canonical code of each declared class (None where it names no landmark) and the problems with them.

    Two classes that mean the same landmark are refused: their instances would silently merge.
    """
    renames = renames or {}
    codes = tuple(canonical_class(renames.get(str(n), n)) for n in raw_names)
    problems = []
    first: dict[str, int] = {}
    for index, (given, code) in enumerate(zip(raw_names, codes)):
        if code is None:
            problems.append(unknown_class_problem(source, index, given))
        elif code in first:
            problems.append(Problem("error", source, None, f"classes {first[code]} ({raw_names[first[code]]!r}) and "
                                    f"{index} ({given!r}) both mean {code}: their poles would merge",
                                    "give each class its own name in the export"))
        else:
            first[code] = index
    return codes, problems


def unknown_class_problem(source: Path, index: int, given) -> Problem:
    """The one message for a class name that names no landmark."""
    return Problem("error", source, None, f"class {index} {str(given)!r} names no landmark",
                   f"rename it to one of {' '.join(CLASSES)} (bands top first), e.g. "
                   f"`poles convert DATA --out NEW --rename '{given}=bp'`")
