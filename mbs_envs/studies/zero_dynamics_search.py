"""The search of ``PlannedSwingUp``'s zero-dynamics hold on the arm's own map under observation noise (the logic of ``scripts/tune_zero_dynamics_hold.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

from typing import Any
import csv
import dataclasses
import itertools
import json
import sys

from tqdm import tqdm
import gymnasium as gym
import numpy as np

from ..controllers import PlannedSwingUp, region
from ..controllers.planned_swingup import HOLD_WINDOW
from ..controllers.swingup import upright_linearization
from .plotting import pyplot, save


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


def run(args: Any) -> None:
    """The search (``scripts/tune_zero_dynamics_hold.py``'s options in ``args``): every law of the grid on the nominal and mismatched plants, then the rescue settings for the best; writes ``zd_search.json``, ``zd_search.csv`` and ``zd_search.png`` to ``args.out`` and prints the pick."""
    args.out.mkdir(parents=True, exist_ok=True)
    env = gym.make(args.env).unwrapped
    ctrl = PlannedSwingUp(env, hold=False, hold_law="zero_dynamics")
    tol = float(getattr(env, "upright_tolerance", 0.1))
    laws = [
        region.ZeroDynamicsHold(rate, reach, omega, trigger=np.inf)
        for rate, reach, omega in itertools.product(args.rates, args.reaches, args.omegas)
    ]
    chunks = [laws[j : j + 16] for j in range(0, len(laws), 16)]  # (16 settings a batch: memory)
    law_shares = np.concatenate([shares(ctrl, part, ctrl.model, args.noise, tol, args.windows, 3.0, args.seed)
                                 for part in tqdm(chunks, desc="law", file=sys.stdout)])  # fmt: skip
    best = laws[int(np.argmax(law_shares))]
    rescues = [
        dataclasses.replace(best, rescue_reach=r, trigger=t, release=s)
        for r, t, s in itertools.product(args.rescue_reaches, args.triggers, args.releases)
    ] + [best]  # fmt: skip  (the last: no rescue)
    plants = [0.0] + list(args.mismatch)
    rescue_shares = np.array(
        [
            shares(
                ctrl,
                rescues,
                mismatched(ctrl.model, p) if p else ctrl.model,
                args.noise,
                tol,
                args.windows,
                7.0,
                args.seed,
            )
            for p in tqdm(plants, desc="rescue", file=sys.stdout)
        ]
    ).T  # fmt: skip  (settings, plants)
    pick = int(np.argmax(rescue_shares.mean(axis=1)))
    law_fields, rescue_fields = ["rate", "reach", "omega"], ["rescue_reach", "trigger", "release"]
    with open(args.out / "zd_law.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(law_fields + ["share"])
        w.writerows([[getattr(zd, k) for k in law_fields] + [f"{s:.4f}"] for zd, s in zip(laws, law_shares)])
    with open(args.out / "zd_rescue.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(rescue_fields + [f"share at p={p:g}" for p in plants] + ["mean"])
        w.writerows([[getattr(zd, k) for k in rescue_fields] + [f"{s:.4f}" for s in row] + [f"{row.mean():.4f}"]
                     for zd, row in zip(rescues, rescue_shares)])  # fmt: skip
    as_dict = lambda zd: {k: (None if not np.isfinite(v) else v) for k, v in dataclasses.asdict(zd).items()}  # noqa: E731
    (args.out / "zd_search.json").write_text(json.dumps({
        "env": args.env, "noise": args.noise, "seed": args.seed, "windows": args.windows, "plants": plants,
        "best_law": as_dict(best), "best_law_share": float(law_shares.max()), "pick": as_dict(rescues[pick]),
        "pick_shares": rescue_shares[pick].tolist(), "no_rescue_shares": rescue_shares[-1].tolist()}, indent=1))  # fmt: skip
    fig, (a1, a2) = pyplot().subplots(1, 2, figsize=(10, 3.5))
    a1.plot(np.sort(law_shares)[::-1], ".")
    a1.set(xlabel="law setting (by share)", ylabel="share of windows held", title="the law, 3 s of settling")
    for j, p in enumerate(plants):
        a2.plot(rescue_shares[:, j], ".", label=f"masses off by {p:+g}")
    a2.set(xlabel="rescue setting (the last: none)", title="the rescue, 7 s of settling")
    a2.legend(fontsize=7)
    save(fig, args.out / "zd_search.png")
    print(
        f"best law {as_dict(best)}: {law_shares.max():.4f}; pick {as_dict(rescues[pick])}: "
        f"{np.round(rescue_shares[pick], 4).tolist()} (no rescue {np.round(rescue_shares[-1], 4).tolist()})"
    )
