#!/usr/bin/env python
"""Search the zero-dynamics hold of ``PlannedSwingUp`` on the arm's own map under observation noise: the procedure
behind its defaults (``hold_law="zero_dynamics"``; :class:`controllers.region.ZeroDynamicsHold`).

Two stages, both scored by :func:`controllers.region.hold_shares` on the scene's plant (its nonlinear map,
:class:`controllers.region.ArmMap`; a run past the planner's ``drop`` holds nothing more), observed with noise
``--noise`` on every state entry through the steady Kalman filter, the law's coefficients those of the nominal model
(:func:`controllers.region.zero_dynamics`), the share of 2-s windows with both angles within the tolerance:

1. **the law** (no rescue): every ``(rate, reach, omega)`` of the grid (``--rates``, ``--reaches``, ``--omegas``),
   windows after 3 s of settling, all on the same noise (``--seed``);
2. **the rescue**: with the best law of stage 1, every ``(rescue_reach, trigger, release)`` of the grid and no rescue,
   windows after 7 s of settling (a real hold settles that long before the success window; without a rescue the
   law's losses are falls, which a short settle hides), on the nominal plant and on plants whose masses are off the
   model's by each of ``--mismatch`` (``m2``, ``I2`` times ``1 + p``, ``m1`` times ``1 - p``: the identification's
   errors on the tuning episodes are about those of 0.5-1 %), ranked by the mean share over the plants.

Writes ``zd_law.csv``, ``zd_rescue.csv``, ``zd_search.json`` (the settings, the best of each stage) and
``zd_search.png`` to ``--out``::

    python scripts/tune_zero_dynamics_hold.py --out results/zd_hold    # about 2 minutes on one core

The defaults are this search's picks with its default arguments; on the tuning episodes of the whole
swing-up they end 87 % within 0.1 rad with noise 0.01 (``controllers/planned_swingup.py``'s docstring).
"""

from __future__ import annotations

import argparse
import pathlib

import mbs_envs  # noqa: F401
from mbs_envs.studies.zero_dynamics_search import run


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--env", default="mbs_envs/Acrobot-v1", help="the scene (default the acrobot, where the hold pays)")
    p.add_argument("--rates", type=float, nargs="+", default=[10.0, 15.0, 22.5, 35.0, 50.0], help="[1/s]")
    p.add_argument("--reaches", type=float, nargs="+", default=[0.085, 0.09, 0.095, 0.0975], help="[rad]")
    p.add_argument("--omegas", type=float, nargs="+", default=[30.0, 45.0, 60.0, 80.0], help="[rad/s]")
    p.add_argument("--rescue-reaches", type=float, nargs="+", default=[0.15, 0.2, 0.3], help="[rad]")
    p.add_argument("--triggers", type=float, nargs="+", default=[1.1, 1.2, 1.35])
    p.add_argument("--releases", type=float, nargs="+", default=[0.5, 0.7])
    p.add_argument(
        "--mismatch", type=float, nargs="*", default=[-0.02, -0.01, 0.01, 0.02], help="plants' mass errors p"
    )
    p.add_argument("--windows", type=int, default=1000, help="windows per setting and plant")
    p.add_argument("--noise", type=float, default=0.01, help="observation noise std per state entry [rad, rad/s]")
    p.add_argument("--seed", type=int, default=13, help="the windows' noise")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
