"""What every report plot shares: matplotlib on its file-only Agg backend, one DPI, saving.

Imported before pyplot by every report module, so that no report ever opens a window, also on
a machine without a display.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # reports are files: never a window

import matplotlib.pyplot as plt  # after the backend is chosen

__all__ = ["DPI", "plt", "save_figure"]

DPI = 110


def save_figure(fig: Any, path: Path) -> Path:
    """Lay out, write ``path`` as PNG and close ``fig``; returns ``path``."""
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
