"""The search of ``PlannedSwingUp``'s hold on the arm's own map under observation noise (the logic of ``scripts/tune_hold.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any
import csv
import json
import sys

from tqdm import tqdm
import gymnasium as gym
import numpy as np

from ..controllers import PlannedSwingUp, region
from ..controllers.planned_settings import EDGE_Q, HOLD_Q, RECOVER_Q
from ..controllers.planned_swingup import HOLD_SETTLE, HOLD_WINDOW
from ..controllers.swingup import upright_linearization
from .plotting import pyplot, save


#: the search's ranges: log10 of the weights (passive angle, driven angle, rates) of each gain, and the edge [rad],
#: lead [s] and way back [rad]
LOG_HOLD, LOG_EDGE, LOG_RECOVER = (
    ((4.5, -1.5, -1.0), (7.5, 1.0, 1.5)),
    ((-2.5, -2.0, 1.0), (1.5, 1.0, 4.0)),
    ((-2.0, -1.0, -3.0), (3.0, 4.5, 2.0)),
)


EDGE, LEAD, BACK = (0.065, 0.09), (0.0, 0.06), (0.04, 0.1)


def draw(rng: np.random.Generator, make: Callable[..., np.ndarray], n: int) -> list[dict]:
    """``n`` candidates whose three gains all exist and stabilize the linearization (``make`` returns them or raises)."""
    out: list[dict] = []
    while len(out) < n:
        w = [10 ** rng.uniform(*bounds) for bounds in (LOG_HOLD, LOG_EDGE, LOG_RECOVER)]
        try:
            K = make(*w)
        except ValueError:
            continue
        out.append({"hold_q": w[0], "edge_q": w[1], "recover_q": w[2], "K": K, "edge": rng.uniform(*EDGE), "edge_lead": rng.uniform(*LEAD),
                    "hold_back": rng.uniform(*BACK)})  # fmt: skip
    return out


def run(args: Any) -> None:
    """The search (``scripts/tune_hold.py``'s options in ``args``): candidates drawn, scored on the arm's own map, the best checked beside the defaults; writes ``hold_search.csv``, ``hold_search.json`` and ``hold_search.png`` to ``args.out`` and prints the checked rows."""
    args.out.mkdir(parents=True, exist_ok=True)
    env = gym.make(args.env).unwrapped
    base = PlannedSwingUp(env, hold=False, hold_law="edge")  # (the law this search tunes)
    A, B = upright_linearization(base.model)
    with region.quiet_riccati():
        A_d, B_d = region.discretize(A, B, base.dt)
        L = region.steady_kalman(A_d, args.noise)[0]
    arm = region.ArmMap(base.model, base.goal, base.dt, base.substeps, base.drop)
    tol = float(getattr(env, "upright_tolerance", 0.1))

    def make(hold_q: np.ndarray, edge_q: np.ndarray, recover_q: np.ndarray) -> np.ndarray:
        K = PlannedSwingUp(
            env, hold=False, hold_law="edge", hold_q=hold_q, edge_q=edge_q, recover_q=recover_q
        ).hold_gains_of(A[None], B[None])[0]
        if not np.isfinite(K).all():
            raise ValueError("no stabilizing gain")
        return K[:12].reshape(3, 4)  # (the edge law: inside, edge, recovery)

    def score(cands: list[dict], windows: int, seed: int, progress: str) -> np.ndarray:
        out = []
        for j in tqdm(range(0, len(cands), 16), desc=progress, file=sys.stdout):
            part = cands[j : j + 16]
            K = np.stack([c["K"] for c in part])
            out += list(region.hold_shares(A_d, B_d, L, K[:, 0], args.noise, tol, int(round(HOLD_WINDOW / base.dt)), windows,
                                           int(round(HOLD_SETTLE / base.dt)), seed, float(base.u_max[0]), K_e=K[:, 1],
                                           edge=[c["edge"] for c in part], lead=[c["edge_lead"] for c in part], joint=base.driven,
                                           K_r=K[:, 2], band=base.hold_band, back=[c["hold_back"] for c in part], arm=arm))  # fmt: skip
        return np.array(out)

    cands = draw(np.random.default_rng(args.seed), make, args.candidates)
    shares = score(cands, args.windows, 100 + args.seed, "search")
    order = np.argsort(shares)[::-1][: args.top]
    default_cand = {
        "hold_q": HOLD_Q,
        "edge_q": EDGE_Q,
        "recover_q": RECOVER_Q,
        "K": make(HOLD_Q, EDGE_Q, RECOVER_Q),
        "edge": base.edge,
        "edge_lead": base.edge_lead,
        "hold_back": base.hold_back,
    }  # fmt: skip  (base has the default settings)
    checked = [cands[i] for i in order] + [default_cand]
    check = score(checked, args.check_windows, 999, "check")
    fields = ["hold_q", "edge_q", "recover_q", "edge", "edge_lead", "hold_back"]
    listed = lambda c: {k: (np.asarray(c[k]).tolist()) for k in fields}  # noqa: E731
    with open(args.out / "hold_search.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(fields + ["share"])
        for c, s in zip(cands, shares):
            w.writerow([json.dumps(listed(c)[k]) for k in fields] + [f"{s:.4f}"])
    rows = [dict(listed(c), search=(float(shares[i]) if i is not None else None), check=float(s), default=i is None)
            for c, s, i in zip(checked, check, list(order) + [None])]  # fmt: skip
    (args.out / "hold_search.json").write_text(json.dumps({"env": args.env, "noise": args.noise, "seed": args.seed, "windows": args.windows,
                                                            "check_windows": args.check_windows, "checked": rows}, indent=1))  # fmt: skip
    fig, ax = pyplot().subplots(figsize=(6, 3.5))
    ax.plot(np.sort(shares)[::-1], ".", ms=3, label=f"search ({args.windows} windows each)")
    ax.plot(range(len(order)), check[:-1], "x", label=f"best {len(order)}, checked ({args.check_windows} others)")
    ax.axhline(check[-1], color="k", lw=0.8, ls="--", label=f"defaults, checked: {check[-1]:.1%}")
    ax.set(
        xlabel="candidate (by search share)",
        ylabel="share of windows held",
        title=f"hold search, {args.env}, noise {args.noise}",
    )
    ax.legend(fontsize=8)
    save(fig, args.out / "hold_search.png")
    for r in rows:
        print(
            f"{r['check']:.4f}  search {r['search'] if r['search'] is None else round(r['search'], 4)}  "
            + "  ".join(f"{k} {np.round(r[k], 4).tolist()}" for k in fields)
            + ("  (defaults)" if r["default"] else "")
        )
