"""Learning curves of trained agents: each training seed's log (``training_log.csv`` and ``config.json`` written by
:func:`mbs_envs.studies.training.train`) read back, and drawn as the mean over seeds with the range as a band."""

from __future__ import annotations

import csv
import json
import pathlib
from typing import Any

import numpy as np


def read_run(folder: pathlib.Path) -> dict[str, Any] | None:
    """One training run's evaluations (validation return, settled error, failure and success rates against env steps
    and training wall time) and its record, or None where the folder has no log. A shipped agent of a continued run
    has the whole chain's log and budget (:func:`mbs_envs.studies.training.whole_log`)."""
    folder = pathlib.Path(folder)
    path = folder / "training_log.csv"
    if not path.exists():
        return None
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    cfg = json.loads((folder / "config.json").read_text())
    column = lambda key: [float(r[key]) for r in rows]  # noqa: E731
    return {"timesteps": column("timesteps"), "train_wall_s": column("train_wall_s"),
            "rms_error_settled": column("rms_error_settled"), "failure_rate": column("failure_rate"),
            "return": column("return"), "success": [1.0 - x for x in column("failure_rate")],
            "steps": (cfg.get("total") or cfg)["steps"], "seed": cfg["seed"], "command": cfg.get("command"),
            "wall": (cfg.get("total") or cfg)["train_wall_s"], "runs": (cfg.get("total") or {}).get("runs", 1),
            "hyperparameters": cfg.get("hyperparameters"), "n_envs": cfg.get("n_envs"), "init": cfg.get("init"),
            "action_repeat": cfg.get("action_repeat", 1), "kept": cfg.get("kept"),
            "commands": (cfg.get("total") or {}).get("commands") or [cfg.get("command")],
            "evaluated_action_repeat": cfg.get("evaluated_action_repeat")}  # fmt: skip


def training_curves(agents: dict[str, list[str]]) -> dict[str, dict]:
    """Per algorithm (display name -> its seeds' folders): ``{"runs": [read_run(folder), ...]}``; algorithms without
    a log left out."""
    curves = {}
    for name, folders in agents.items():
        runs = [r for r in (read_run(pathlib.Path(f)) for f in folders) if r is not None]
        if runs:
            curves[name] = {"runs": runs}
    return curves


def draw(ax: Any, name: str, runs: list[dict], metric: str, x: str) -> None:
    """``metric`` against ``x`` (``"timesteps"`` or ``"train_wall_s"``) on ``ax``: the mean over the runs (at the
    evaluations every run reached), the band their range; evaluations where every run's value is undefined (NaN: no
    validation episode kept) marked with an x at the top."""
    n = min(len(r[x]) for r in runs)
    xs = np.mean([r[x][:n] for r in runs], axis=0)
    ys = np.array([r[metric][:n] for r in runs], float)
    alive = np.isfinite(ys).any(axis=0)
    mean = np.full(n, np.nan)
    lo, hi = mean.copy(), mean.copy()
    mean[alive] = np.nanmean(ys[:, alive], axis=0)
    lo[alive], hi[alive] = np.nanmin(ys[:, alive], axis=0), np.nanmax(ys[:, alive], axis=0)
    line = ax.plot(xs, mean, "o-", ms=3, label=f"{name} ({len(runs)} seed{'s' if len(runs) > 1 else ''})")[0]
    if len(runs) > 1:
        ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2)
    if not alive.all():
        ax.plot(xs[~alive], np.full((~alive).sum(), 0.97), "x", color=line.get_color(), transform=ax.get_xaxis_transform(),
                label=f"{name}: all validation episodes failed")  # fmt: skip
