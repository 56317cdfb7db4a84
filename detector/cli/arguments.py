"""The argument types and shared arguments of the ``poles`` commands: every number finite, every count whole,
every refusal one line that argparse prints with the command's usage."""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


def image_size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size {text!r} is not WIDTHxHEIGHT, e.g. 640x480") from None
    if width < 32 or height < 32:
        raise argparse.ArgumentTypeError(f"size {text!r} is too small (at least 32x32)")
    return width, height


def confidence(text: str) -> float:
    """A ``--conf`` value: a number between 0 and 1 (``naoslam.perception.yolo.valid_confidence``)."""
    from naoslam.perception.pole_model import valid_confidence

    try:
        return valid_confidence(float(text))
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"{text!r}: {error}") from None


def finite_number(text: str) -> float:
    """An argparse type for a real number: ``float`` also takes ``nan`` and ``inf``, which no setting means."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive_number(text: str) -> float:
    """An argparse type for a finite number above 0 (a duration, a scale)."""
    value = finite_number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number above 0")
    return value


#: The longest budget a time option takes, in minutes: a week. A larger one is a slip, and overflows the planner's
#: arithmetic to infinity.
MAX_MINUTES = 7 * 24 * 60


def minutes_number(text: str) -> float:
    """An argparse type for a time budget in minutes: above 0 and at most ``MAX_MINUTES``."""
    value = positive_number(text)
    if value > MAX_MINUTES:
        raise argparse.ArgumentTypeError(f"{text!r}: give at most {MAX_MINUTES} minutes (a week)")
    return value


def whole_number(minimum: int) -> Callable[[str], int]:
    """An argparse type for a count or a seed: a whole number, ``minimum`` or more."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value}: give {minimum} or more")
        return value

    return parse


def number_list(names: str, positive: bool = False) -> Callable[[str], tuple[float, ...]]:
    """An argparse type for comma-separated finite numbers (above 0 if ``positive``), one per name in ``names``
    (e.g. ``"X,Y,THETA"``)."""
    count = len(names.split(","))

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(finite_number(v) for v in text.split(","))
        except argparse.ArgumentTypeError:
            values = ()
        if len(values) != count or (positive and min(values) <= 0):
            kind = "positive numbers" if positive else "numbers"
            raise argparse.ArgumentTypeError(f"{text!r}: give {names} as {count} {kind} separated by commas")
        return values

    return parse


def thread_choice(text: str) -> int | str:
    if text in ("auto", "shared", "all"):
        return text
    try:
        return whole_number(1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"--threads {text!r}: give a number of threads (1 or more), `shared`, `all` "
                                         "or `auto`") from None


def add_dataset_argument(parser: argparse.ArgumentParser, description: str) -> None:
    """The dataset as a first positional DATA or, as every other command takes it, as ``--data DATA``."""
    parser.add_argument("data", type=Path, nargs="?", help=description)
    parser.add_argument("--data", dest="data_option", type=Path, metavar="DATA", help="the same as DATA")


def add_input_width_argument(parser: argparse.ArgumentParser, applies: str = "") -> None:
    """``--imgsz W``: run the ONNX model at W px wide (``LandmarkDetector(input_width=W)``), as a slower CPU would."""
    parser.add_argument("--imgsz", type=int, help=f"{applies}the model's input width, e.g. 320 for a slower CPU (a "
                                                  "model exported with --dynamic; default: its own)")


def existing(*paths: Path | None) -> tuple[Path, ...]:
    """The given paths that exist: the inputs an output folder must never overlap (`shipped` and the like are not
    paths)."""
    return tuple(path for path in paths if path is not None and path.exists())


def one_dataset(args: argparse.Namespace) -> Path:
    """The dataset given as DATA or ``--data``, whichever was given (refused when neither or two differ)."""
    given = {path for path in (args.data, args.data_option) if path is not None}
    if len(given) != 1:
        raise ValueError("give the dataset once, as DATA or as --data DATA")
    return given.pop()


@contextmanager
def flags_for(parameters: dict[str, str]) -> Iterator[None]:
    """Put the command's flag beside a runtime error that names one of ``parameters`` (parameter -> flag) first:
    naoslam's messages name its own parameters (``min_views 0 must be at least 1``), the user typed the flag."""
    try:
        yield
    except ValueError as error:
        parameter = str(error).split(" ", 1)[0]
        if parameter in parameters:
            raise ValueError(f"{parameters[parameter]}: {error}") from None
        raise
