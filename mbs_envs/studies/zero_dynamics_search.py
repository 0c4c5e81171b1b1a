"""The search of ``PlannedSwingUp``'s zero-dynamics hold on the arm's own map under observation noise (the logic of ``scripts/tune_zero_dynamics_hold.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import dataclasses
import numpy as np
import mbs_envs  # noqa: F401
from ..controllers import PlannedSwingUp, region
from ..controllers.planned_swingup import HOLD_WINDOW
from ..controllers.swingup import upright_linearization


def mismatched(model, p: float):
    """``model`` (a :class:`mbs_envs.models.planar2r.Planar2R`) with ``m2``, ``I2`` times ``1 + p`` and ``m1`` times
    ``1 - p``."""
    q = model.params
    return type(model)(
        dataclasses.replace(q, m2=q.m2 * (1 + p), I2=q.I2 * (1 + p), m1=q.m1 * (1 - p)), driven=model.driven
    )


def shares(ctrl: PlannedSwingUp, settings: list[region.ZeroDynamicsHold], plant, noise: float, tol: float, windows: int, settle: float,
           seed: int) -> np.ndarray:  # fmt: skip
    """The share of windows each of ``settings`` holds on ``plant``'s map, the law's coefficients and the filter those of
    ``ctrl``'s nominal model: one batch, the settings' fields stacked as ``(G, 1)`` arrays (they broadcast against the
    ``(G, windows)`` members of :func:`controllers.region.hold_shares`), every setting on the same noise."""
    A, B = upright_linearization(ctrl.model)
    with region.quiet_riccati():
        A_d, B_d = region.discretize(A, B, ctrl.dt)
        L = region.steady_kalman(A_d, noise)[0]
    terms = ctrl.hold_gains_of(A[None], B[None])[0]
    arm = region.ArmMap(plant, ctrl.goal, ctrl.dt, ctrl.substeps, ctrl.drop)
    steps = lambda t: int(round(t / ctrl.dt))  # noqa: E731
    G = len(settings)
    zd = region.ZeroDynamicsHold(**{f.name: np.array([getattr(z, f.name) for z in settings], float)[:, None]
                                    for f in dataclasses.fields(region.ZeroDynamicsHold)})  # fmt: skip
    stack = lambda a: np.repeat(a[None], G, axis=0)  # noqa: E731
    return region.hold_shares(A_d, B_d, L, stack(terms[12:]), noise, tol, steps(HOLD_WINDOW), windows, steps(settle), seed, float(ctrl.u_max[0]),
                              K_r=stack(terms[8:12]), back=ctrl.hold_back, arm=arm, coef=stack(terms[:7]), zd=zd)  # fmt: skip
