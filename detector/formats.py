"""The format of every JSON file poles writes for people and their scripts to read: one number per kind of file,
defined here and nowhere else.

Each such file is an object that starts with ``"format"`` (the number), ``"kind"`` and ``"written_by"`` (the poles
release); a list of rows is kept under ``"rows"``. A kind's number moves whenever a field of it is renamed, moved or
removed (adding one does not break a reader, and still moves it); ``tests/test_formats.py`` fails when a field
changes and the number does not. :func:`read_record` hands back the data of a file of the current number; a file of
another number is refused saying which release wrote it and what to do. A file without a number was written before
numbers were kept: it reads as format 1, which is what every kind was then (the evaluation's metrics, whose counts
have since moved under ``counts``, are format 2).
"""
from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

from detector.atomic import write_json

#: Kind of file -> its format number now. What each holds is listed in docs/commands.md ("Files and their formats").
FORMATS: dict[str, int] = {
    "evaluation": 2,  # poles evaluate's metrics.json (2: TP/FP/FN/TN under "counts"; 1 had them at the top)
    "finetune": 3,  # poles finetune's metrics.json (2: replan, the plan after training; the plan's epoch estimate;
    # 3: the teacher's disputed frames)
    "slam": 1,  # poles slam's metrics.json
    "slam map": 1,  # poles slam's map.json
    "slam comparison": 1,  # poles slam --compare's comparison.json
    "calibration": 1,  # poles calibrate's calibration.json
    "export report": 1,  # poles export's MODEL.export.json
    "stages": 1,  # the stages.json of poles demo and poles finetune
    "robot training": 4,  # poles train-robot's history.json (2: second_look_crops; 3: preclassifier; 4: teacher added)
    "augment": 1,  # poles augment's augment.json
    "paint": 1,  # paint.json of poles synth --paint-from and poles finetune
    "demo evaluation": 1,  # poles demo's evaluation/summary.json
    "demo slam": 1,  # poles demo's slam/summary.json
    "demo speed": 1,  # poles demo's speed/summary.json
    "judgement": 1,  # poles finetune's evaluation/summary.json
    "pick": 1,  # poles pick's picked.json
    "annotations": 1,  # annotations.json beside the frames poles synth renders (and poles split copies)
}
#: The keys every file starts with.
STAMP_KEYS = ("format", "kind", "written_by")
#: Where a file that is a list of rows keeps them.
ROWS = "rows"


class FormatMismatch(ValueError):
    """A file of another kind, or of another format number than this release reads."""


@cache
def release() -> str:
    """This poles release, as ``written_by`` names it."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"poles {version('nao-poles')}"
    except PackageNotFoundError:
        return "poles (not installed)"


def stamped(kind: str, data: dict[str, Any] | list) -> dict[str, Any]:
    """``data`` with the stamp of ``kind`` in front (a list goes under ``rows``)."""
    body = {ROWS: data} if isinstance(data, list) else data
    return {"format": FORMATS[kind], "kind": kind, "written_by": release(), **body}


def write_record(path: Path | str, kind: str, data: dict[str, Any] | list) -> Path:
    """Write ``data`` as a file of ``kind`` at ``path`` (atomically)."""
    return write_json(path, stamped(kind, data))


def read_record(path: Path | str, kind: str) -> dict[str, Any]:
    """The data of a file of ``kind`` without its stamp (a list of rows as ``{"rows": [...]}``); ``FormatMismatch``
    naming the file, the release that wrote it and what to do when it is of another kind or number; ``ValueError``
    when it is not JSON."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not poles's {kind} file (not JSON: {type(error).__name__}) - give the file poles "
                         "wrote") from None
    if isinstance(data, list):  # a list of rows, written before numbers were kept
        data = {ROWS: data}
    if not isinstance(data, dict):
        raise FormatMismatch(f"{path}: holds a {type(data).__name__}, not poles's {kind} file")
    found_kind = data.get("kind", kind)
    if found_kind != kind:
        raise FormatMismatch(f"{path}: a {found_kind} file, not a {kind} file - give the {kind} file")
    number = data.get("format", 1)
    if not isinstance(number, int) or isinstance(number, bool):
        raise FormatMismatch(f"{path}: its \"format\" is {json.dumps(number)}, not a whole number - the file was "
                             f"edited or damaged; give the {kind} file poles wrote (run the command that wrote it "
                             "again)")
    if number != FORMATS[kind]:
        writer = data.get("written_by", "a poles release from before format numbers")
        newer = isinstance(number, int) and number > FORMATS[kind]
        fix = ("update poles to read it" if newer else
               "run the command that wrote it again with this release, or read it with the release that wrote it")
        raise FormatMismatch(f"{path}: {kind} format {number}, written by {writer}; {release()} reads format "
                             f"{FORMATS[kind]} - {fix} (docs/commands.md lists what changed)")
    return {key: value for key, value in data.items() if key not in STAMP_KEYS}
