"""Where a command may write: the one rule every command that writes calls, so nothing a user owns is ever lost.

- A command's **inputs** are everything it reads: a dataset's root, its split folders and the folder its data.yaml's
  ``path:`` names (``Dataset.input_folders``), a COCO file's folder, the models, weights and calibrations it is
  given. No output may be, hold or lie inside an input, ``--force`` or not.
- No output lies inside a dataset it was not asked to write (a folder holding a ``data.yaml``): its images would be
  read back as that dataset's.
- An output **folder** is written whole into a temporary sibling and moved into place, with a record
  (``OUTPUT_MARKER``) of the kind of output and every file written. ``--force`` replaces an existing folder only
  when that record names the same kind and the folder holds nothing else; otherwise the command is refused, naming
  the files poles did not write.
- An output **file** is replaced only with ``--force``, and never when it is an input.
- A resumable run (``poles demo``, ``poles finetune``) owns its folder once ``StageLedger.check_folder`` has
  accepted it: a stage that runs again replaces its own subfolder whole (``stage_folder``).
- A refused command has written nothing. A report of a read-only command that has nowhere to go is written under a
  new name (:func:`fresh_path`), never over a file.
"""
from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from detector.atomic import atomic_folder

#: The record in every output folder: which kind of output poles wrote there, and its files.
OUTPUT_MARKER = ".poles-output"
#: Files named when a folder holds some that poles did not write.
NAMED_FILES = 5


def check_output_folder(out: str | Path, force: bool, inputs: Iterable[Path], kind: str) -> Path:
    """The resolved output folder, or an error naming the fix: it is a file, overlaps an input or lies inside
    another dataset (never allowed), or holds files and ``force`` is not set, or holds another kind of output or
    files poles did not write."""
    out = Path(out).resolve()
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out} is a file: give a folder")
    check_placement(out, inputs)
    if out.exists() and any(out.iterdir()):
        if not force:
            raise FileExistsError(f"{out} exists and is not empty: choose another --out or pass --force to replace it")
        _refuse_foreign(out, kind)
    return out


def check_output_file(out: str | Path, force: bool, inputs: Iterable[Path]) -> Path:
    """The resolved output file, or an error: it is a folder, is an input or lies in one (never allowed, even with
    ``force``), lies inside another dataset, or exists and ``force`` is not set."""
    out = Path(out).resolve()
    if out.is_dir():
        raise IsADirectoryError(f"{out} is a folder: give a file name")
    check_placement(out, inputs)
    if out.exists() and not force:
        raise FileExistsError(f"{out} exists - pick another name or add --force to replace it")
    return out


@contextmanager
def output_folder(out: str | Path, force: bool, inputs: Iterable[Path], kind: str) -> Iterator[Path]:
    """A temporary folder for a command's output, moved to ``out`` (checked first by ``check_output_folder``) when
    the block succeeds with its record written, so ``out`` holds one run's files and never half of one."""
    with atomic_folder(check_output_folder(out, force, inputs, kind)) as tmp:
        yield tmp
        mark_output(tmp, kind)


@contextmanager
def stage_folder(folder: str | Path, inputs: Iterable[Path], kind: str) -> Iterator[Path]:
    """A stage's subfolder of a resumable run's own folder, written whole and replacing the stage's earlier one
    (files and all: the run owns it); it may still never overlap an input."""
    folder = Path(folder).resolve()
    check_placement(folder, inputs)
    with atomic_folder(folder) as tmp:
        yield tmp
        mark_output(tmp, kind)


def mark_output(folder: Path, kind: str) -> None:
    """Record ``folder`` as poles's output of ``kind``, with every file in it, so a later ``--force`` may replace
    exactly that."""
    files = sorted(str(path.relative_to(folder)) for path in folder.rglob("*") if path.is_file()
                   and path.name != OUTPUT_MARKER)
    (folder / OUTPUT_MARKER).write_text(json.dumps({"written_by": "poles", "kind": kind, "files": files}),
                                        encoding="utf-8")


def fresh_path(path: Path) -> Path:
    """``path`` if nothing is there, else the first free ``stem-2.suffix``, ``stem-3.suffix``, ...: a report never
    replaces a file."""
    path = candidate = Path(path)
    number = 2
    while candidate.exists():
        candidate = path.with_name(f"{path.stem}-{number}{path.suffix}")
        number += 1
    return candidate


def check_placement(out: str | Path, inputs: Iterable[Path]) -> None:
    """Refuse an output under a file, overlapping an input, or inside a dataset poles is not writing (a resumable
    run folder checks only this, then keeps what is inside itself)."""
    out = Path(out).resolve()
    parent = next((folder for folder in out.parents if folder.exists()), None)
    if parent is not None and not parent.is_dir():
        raise NotADirectoryError(f"--out {out}: {parent} is a file, so nothing can be written under it - choose a "
                                 "path inside a folder")
    for guarded in inputs:
        guarded = Path(guarded).resolve()
        if out == guarded or guarded in out.parents or out in guarded.parents:
            raise ValueError(f"--out {out} overlaps the input {guarded}: choose another path (inputs are never "
                             "written)")
    dataset = next((folder for folder in out.parents if (folder / "data.yaml").is_file()), None)
    if dataset is not None:
        raise ValueError(f"--out {out} lies inside the dataset {dataset} (it holds data.yaml): its files would be "
                         "read as that dataset's - choose a path outside it")


def _refuse_foreign(out: Path, kind: str) -> None:
    """Refuse to replace a folder that is not poles's earlier output of the same kind, or that holds files poles
    did not write there."""
    marker = out / OUTPUT_MARKER
    if not marker.is_file():
        raise FileExistsError(f"{out} holds files that poles did not write (no {OUTPUT_MARKER} in it), so "
                              "--force does not replace it: choose another --out, or move that folder away yourself")
    record = _record(marker)
    if record is None:
        others = sorted(str(path.relative_to(out)) for path in out.rglob("*")
                        if path.is_file() and path.name != OUTPUT_MARKER)
        if not others:
            return
        raise FileExistsError(f"{out} holds {_named(others)} beside a {OUTPUT_MARKER} that lists no files (an earlier "
                              "release's, or not poles's), so poles cannot tell which it wrote and --force does not "
                              "replace it: choose another --out, or move that folder away yourself")
    if record.get("kind") != kind:
        raise FileExistsError(f"{out} holds poles's {record.get('kind')} output, not a {kind}: --force replaces only "
                              "the same kind - choose another --out")
    written = set(record.get("files", []))
    foreign = sorted(str(path.relative_to(out)) for path in out.rglob("*")
                     if path.is_file() and path.name != OUTPUT_MARKER and str(path.relative_to(out)) not in written)
    if foreign:
        raise FileExistsError(f"{out} holds files poles did not write there ({_named(foreign)}), so --force does not "
                              "replace it: move them away, or choose another --out")


def _named(files: list[str]) -> str:
    """The first ``NAMED_FILES`` of ``files``, and how many more."""
    more = f" and {len(files) - NAMED_FILES} more" if len(files) > NAMED_FILES else ""
    return ", ".join(files[:NAMED_FILES]) + more


def _record(marker: Path) -> dict | None:
    """The marker's record; None for one it cannot read (an earlier release's plain-text marker)."""
    try:
        record = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None
