"""Matplotlib without a display, and figures written atomically: the one place plots are saved from."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from naoslam.atomic import atomic_path  # noqa: E402


def save_figure(fig, png: Path | str, dpi: int = 90) -> Path:
    """Write ``fig`` to ``png`` atomically and close it."""
    with atomic_path(png) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)
    return Path(png)
