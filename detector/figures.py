"""Matplotlib without a display, and figures written atomically: the one place plots are saved from."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # noqa: E402

from detector.atomic import atomic_path  # noqa: E402


def save_figure(fig, png: Path | str, dpi: int = 90) -> Path:
    """Write ``fig`` to ``png`` atomically and close it."""
    with atomic_path(png) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)
    return Path(png)


def log_log(ax) -> None:
    """Both axes logarithmic, labelled in plain numbers at 1, 2 and 5 of each decade (0.5, 1, 2, 5, 10, 20 ...):
    matplotlib's own labels for an axis spanning about a decade are powers of ten that run into each other."""
    for axis, scale in ((ax.xaxis, ax.set_xscale), (ax.yaxis, ax.set_yscale)):
        scale("log")
        axis.set_major_locator(LogLocator(subs=(1, 2, 5)))
        axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        axis.set_minor_formatter(NullFormatter())
