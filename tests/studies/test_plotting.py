"""The scripts' figure helper."""

from __future__ import annotations

import warnings

import pytest

from mbs_envs.studies.plotting import pyplot, save


def test_a_figure_tight_layout_cannot_fit_is_saved_whole_and_quietly(tmp_path):
    pytest.importorskip("matplotlib", reason="matplotlib (the plots extra) is not installed")
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(2, 1.2))
    fig.suptitle("a title\nof two lines\nand a third", fontsize=14)  # more than the figure's height
    ax.set_xlabel("x")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib's "Tight layout not applied" would fail here
        save(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 0
