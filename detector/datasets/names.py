"""Map the class names a dataset uses onto the canonical landmark codes (by name, never by index).

Every command reads class names through ``class_codes``, so every command accepts and refuses the same names in
the same words.
"""
from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

from detector.datasets.model import Problem
from naoslam.landmarks import CLASSES

_COLOUR_LETTER = {"pink": "p", "magenta": "p", "blue": "b", "cyan": "b", "yellow": "y", "green": "g"}
#: A colour word, also where names run words together ("BluePink", "sky blue" and "SkyBlue" read as blue).
_COLOUR_WORD = re.compile("|".join(_COLOUR_LETTER))


def canonical_class(name: str) -> str | None:
    """The canonical code for a dataset's class name, or None when it names no landmark.

    Accepts the codes themselves in any case (``"BP"``), with separators (``"b-p"``), beside other words
    (``"pole_bp"``, ``"BP pole"``), and colour words top band first, apart or run together (``"blue-pink"``,
    ``"Blue over Pink"``, ``"sky blue / pink"``, ``"BluePink"``).
    """
    text = str(name).strip().lower()
    compact = re.sub(r"[^a-z]", "", text)
    if compact in CLASSES:
        return compact
    letters = [_COLOUR_LETTER[word] for word in _COLOUR_WORD.findall(text)]
    if letters:
        code = "".join(letters)
        return code if code in CLASSES else None
    codes = [w for w in re.findall(r"[a-z]+", text) if w in CLASSES]
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


def class_codes(raw_names: list, source: Path, renames: dict[str, str] | None = None, ids: list | None = None,
                nouns: str = "classes") -> tuple[tuple[str | None, ...], list[Problem]]:
    """The canonical code of each declared class (None where it names no landmark) and the problems with them.

    Two classes that read as one landmark merge only where the user's ``renames`` name both of them (a deliberate
    merge, said in a note); otherwise they are refused, as their instances would silently merge. ``ids`` and
    ``nouns`` name the classes as their file does (a COCO category's own id, not its index). A class that names no
    landmark is judged by ``unknown_class_problems`` once the outlines are read.
    """
    renames = renames or {}
    codes = tuple(canonical_class(renames.get(str(n), n)) for n in raw_names)
    problems = []
    first: dict[str, int] = {}

    def label(index: int) -> str:
        return f"{ids[index] if ids is not None else index} ({raw_names[index]!r})"

    for index, (given, code) in enumerate(zip(raw_names, codes)):
        if code is None:
            continue
        if code not in first:
            first[code] = index
            continue
        earlier = raw_names[first[code]]
        pair = f"{nouns} {label(first[code])} and {label(index)}"
        renamed = [str(name) for name in (earlier, given) if str(name) in renames]
        if len(renamed) == 2:
            problems.append(Problem("note", source, None, f"{pair} both read as {code}, as --rename asks: their poles "
                                    "are one landmark class", "nothing to do"))
        elif renamed:
            problems.append(Problem("error", source, None, f"{pair} both mean {code}: your --rename "
                                    f"'{renamed[0]}={code}' puts one onto the other and their poles would merge",
                                    f"rename '{renamed[0]}' to another code, or merge the two on purpose with --rename "
                                    f"'{earlier}={code}' --rename '{given}={code}'"))
        else:
            problems.append(Problem("error", source, None, f"{pair} both mean {code}: their poles would merge",
                                    f"give each class its own name in the export, or merge the two on purpose with "
                                    f"--rename '{earlier}={code}' --rename '{given}={code}'"))
    return codes, problems


#: The words every refusal of a class that names no landmark but labels outlines carries (``--fix`` looks for them).
UNNAMED_CLASS_OUTLINES = "names no landmark and labels"


def unknown_class_problems(source: Path, raw_names: list, codes: tuple[str | None, ...], outlines: Counter,
                           ids: list | None = None, noun: str = "class") -> list[Problem]:
    """The one rule for a declared class that names no landmark: an error where outlines are labelled with it (they
    cannot be read as any pole), a note where none is (ignored: Roboflow lists every class of a project, and a
    rename to a pole's code would clash with that pole's own class). ``outlines`` counts them by class index;
    ``ids`` and ``noun`` name each class as its file does (a COCO category's own id, not its index)."""
    problems = []
    for index, (given, code) in enumerate(zip(raw_names, codes)):
        if code is not None:
            continue
        name = f"{noun} {ids[index] if ids is not None else index} {str(given)!r}"
        if outlines[index]:
            problems.append(Problem("error", source, None, f"{name} {UNNAMED_CLASS_OUTLINES} {outlines[index]} "
                                    "outline(s)", f"if it is a pole class, read it as one: add `--rename "
                                    f"'{given}=CODE'` to `poles finetune`, or write a renamed copy with `poles "
                                    f"convert DATA --out NEW --rename '{given}=CODE'`, CODE one of {' '.join(CLASSES)} "
                                    "(bands top first); if not, delete its outlines"))
        else:
            problems.append(Problem("note", source, None, f"{name} names no landmark and labels no outline: ignored",
                                    "nothing to do"))
    return problems
