"""Headless figure helpers for the scripts (matplotlib is in the ``plots`` extra)."""

from __future__ import annotations

import pathlib
import warnings
from typing import Any


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: pathlib.Path, dpi: int = 110, rect: tuple | None = None) -> None:
    """Lay out (within ``rect`` of the figure, leaving room for a figure legend), write and close a figure.

    Where matplotlib's tight layout cannot fit the decorations (a small figure with a two-line title: its
    "Tight layout not applied" warning), the figure is saved with ``bbox_inches="tight"`` instead, which
    grows the canvas to hold them; no warning reaches the user. Other warnings pass through."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fig.tight_layout(rect=rect)
    fits = True
    for w in caught:
        if "Tight layout not applied" in str(w.message):
            fits = False
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    fig.savefig(path, dpi=dpi, bbox_inches=None if fits else "tight")
    pyplot().close(fig)
