"""Headless figure helpers for the scripts (matplotlib is in the ``plots`` extra)."""

from __future__ import annotations

import pathlib
from typing import Any


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: pathlib.Path, dpi: int = 110, rect: tuple | None = None) -> None:
    """Lay out (within ``rect`` of the figure, leaving room for a figure legend), write and close a figure."""
    fig.tight_layout(rect=rect)
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
