#!/usr/bin/env python
"""The main job: RL agents against model-based controllers on every scene.

For each scene (Planar2R, FourBar, SerialChain and SpatialChain with 10 links, RollingDisk, SliderCrank and
CartDoublePendulum (derived from their Lagrangians), Acrobot, Pendubot) the
model-based controllers with their tuned gains (PD, PD + gravity, computed
torque; on the disk LQR, PD steering, no control; ``scripts/tune.py``) and the
shipped agents (``agents/<id>/<algo>/seed<k>/``: PPO, TD3 and residual PPO on
top of the best model-based controller, every training seed) are rolled out
on the same held-out test seeds through ``predict``:

- nominal plant; model mismatch (masses and lengths of the plant x (1 +- 0.2),
  controllers keep the nominal model; ``--full`` adds 10 and 30 %); observation noise;
  a one-control-step input delay;
- the swing-up scenes (Acrobot, Pendubot) are scored by success (upright for the last
  2 s), time to swing up and the motor's energy;
- per policy and condition: success rate, and over the successful episodes
  the settled RMS error, max error, torque, with 95 % bootstrap confidence
  intervals over training seeds and test episodes; "best" per side among
  policies with >= 95 % success;
- compute per action (single thread, nominal and noisy observations);
- learning curves of every algorithm (mean and range over training seeds)
  against env steps and training wall time, model-based errors as lines;
- actuator sizing by inverse dynamics over the references of all test seeds,
  and the start transient of the best controller;
- a six-axis robustness sweep of every policy (model parameters, velocity noise, torque
  noise, torque response, delay, torque pulses; ``mbs_envs/studies/scene_robustness.py``,
  5 values per axis here, ``scripts/robustness.py`` for more).

Writes ``report.md``, ``episodes.csv``, ``summary.json`` and PNG plots to ``--out``.
Cells run in local processes, or on Ray with ``--ray [ADDRESS]``.

    python scripts/compare.py --out results            # 20 seeds, nominal, +-20 %, noise (~4 min on 2 cores)
    python scripts/compare.py --out results --quick    # 3 seeds
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

# every core busy with this script's processes: kernels compile before they run (mbs_envs/dynamics/background.py)
os.environ.setdefault("MBS_ENVS_JIT", "sync")

import mbs_envs  # noqa: E402,F401  (registers the ids)
from mbs_envs.studies import comparison as cmp  # noqa: E402
from mbs_envs.studies import provenance  # noqa: E402
from mbs_envs.studies.main_job import ROOT, portable, run  # noqa: E402,F401  (the library: mbs_envs.studies.main_job)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--seeds", type=int, default=20, help="test episodes per policy and condition (default 20)")
    p.add_argument("--swing-up-seeds", type=int, default=100, help="test episodes on the swing-up scenes (default 100)")
    p.add_argument("--quick", action="store_true", help="3 test seeds")
    p.add_argument("--full", action="store_true", help="also +-10 %% and +-30 %% mismatch")
    p.add_argument("--scene", action="append", choices=list(cmp.SCENES), help="scene(s) (default all)")
    p.add_argument("--agents", type=pathlib.Path, default=ROOT / "agents", help="folder of shipped agents")
    p.add_argument("--no-agents", action="store_true", help="model-based controllers only")
    p.add_argument("--workers", type=int, default=2, help="local processes")
    p.add_argument("--ray", nargs="?", const="local", help="run the cells on Ray (ADDRESS, or a local instance)")
    p.add_argument(
        "--robustness-values",
        type=int,
        default=5,
        help="values per axis of the robustness sweep (default 5; --quick 2)",
    )
    p.add_argument(
        "--robustness-seeds", type=int, default=1, help="test seeds per value of the robustness sweep (default 1)"
    )
    p.add_argument(
        "--robustness-pulses",
        type=int,
        default=10,
        help="perturbation episodes of the robustness sweep (default 10; --quick 2)",
    )
    p.add_argument("--no-robustness", action="store_true", help="skip the robustness sweep")
    p.add_argument(
        "--plots-only",
        action="store_true",
        help="redraw comparison_<scene>.png from the summary.json already in --out (no evaluation)",
    )
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    provenance.pin_numerics()  # before torch loads, here and in the workers (mbs_envs/studies/provenance.py)
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
