"""Designing a swing-up for the DFKI simulation score (v2): a smooth torque searched against the leaderboard's formula.

The protocol's score, ``1 - mean_k tanh(pi c_k / n_k)`` over swing-up time, energy, torque cost, torque smoothness
and velocity cost (:mod:`mbs_envs.studies.dfki`), is a functional of the episode's trajectory. On the nominal plant
(the protocol simulates it without noise, and every published entry is tuned on it) the episode of
:class:`~mbs_envs.controllers.scored_swingup.ScoredSwingUp` is its feedforward's trajectory followed by the upright
LQR, so the score of a design can be computed from a rollout of the design alone (:func:`design_score`; a compiled
loop, a few milliseconds) and searched directly:

1. **First swing-ups**: iLQR (:func:`mbs_envs.controllers.trajectory.ilqr`: effort weight ``w_u``, a running weight
   ``w_v`` on the rates, a terminal weight toward upright) within ``horizon`` seconds on knots 0.01 s apart, from
   sinusoids of a few periods and amplitudes; each that ends at upright sampled every ``knot_dt`` seconds and fitted
   by least squares so that its spline ends at upright too (:func:`fit_knots`).
2. **The score's own search**: the knots moved by a (1+1) evolution strategy on ``-score`` (:func:`search`; a
   failed rollout scores ``1 +`` its distance from upright at the end: worse than any success), from the best
   first swing-ups; the best kept.

The search is derivative-free because the score is not smooth in the knots: the swing-up time jumps by a control
step where the threshold is crossed a step later, and success is all or nothing. SciPy's derivative-free methods
were not enough: its bounded Powell returned points worse than its start on this objective.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym

import numpy as np
from scipy.optimize import least_squares

from ..controllers import trajectory as traj
from ..controllers.swingup import upright_lqr
from ..controllers.scored_swingup import ScoredSwingUp, closed_loop, feedforward
from ..envs.swingup import Q_DOWN, Q_UP
from . import dfki


@dataclasses.dataclass(frozen=True)
class Plant:
    """What a rollout needs of a protocol env: its model's kernel parameters, driven joint, steps and limits."""

    theta: np.ndarray
    driven: int
    dt: float
    substeps: int
    steps: int
    u_max: float
    K: np.ndarray
    l1: float
    l2: float

    @classmethod
    def of(cls, env: Any) -> "Plant":
        """The plant of a protocol env (``gym.make("mbs_envs/AcrobotDFKI-v1")``), with the upright LQR of
        :class:`ScoredSwingUp`'s defaults."""
        base = env.unwrapped
        model, p = base.model, base.model.params
        K = upright_lqr(model, ScoredSwingUp.Q, np.eye(1))[0]  # (the controller's default lqr_r = 1)
        return cls(np.asarray(model.kernel_params(), float).reshape(-1, 1), int(model.driven[0]), float(base.dt),
                   int(base.substeps), int(env.spec.max_episode_steps), float(base.u_max[0]),
                   np.asarray(K, float).reshape(4), float(p.l1), float(p.l2))  # fmt: skip


def rollout(plant: Plant, knots: np.ndarray, knot_dt: float) -> dict[str, np.ndarray]:
    """The nominal episode of a design, recorded as :func:`mbs_envs.studies.dfki.record` records one: ``T``, ``q``,
    ``v``, ``u`` (both joints)."""
    U = feedforward(knots, knot_dt, plant.dt, plant.u_max)
    X = np.zeros((plant.steps, 4))
    X[0, :2] = Q_DOWN
    u = np.empty(plant.steps)
    goal = np.concatenate([Q_UP, np.zeros(2)])
    closed_loop(U, plant.K, goal, plant.u_max, plant.driven, plant.theta, plant.dt, plant.substeps, plant.steps, X, u)
    U2 = np.zeros((plant.steps, 2))
    U2[:, plant.driven] = u
    return {"T": np.arange(plant.steps) * plant.dt, "q": X[:, :2], "v": X[:, 2:], "u": U2}


def design_score(plant: Plant, knots: np.ndarray, knot_dt: float) -> tuple[float, dict[str, float]]:
    """``(objective, criteria)`` of a design: ``-score`` where it succeeds, else ``1 +`` the largest wrapped entry of
    the final state's distance from upright (worse than any success); the criteria with the score."""
    run = rollout(plant, knots, knot_dt)
    if not np.all(np.isfinite(run["q"])):
        return 10.0, {"success": 0.0, "score": 0.0}
    c = dfki.criteria(run["T"], run["q"], run["v"], run["u"], plant.l1, plant.l2)
    c["score"] = dfki.score(c) if c["success"] else 0.0
    if c["success"]:
        return -c["score"], c
    e = np.concatenate([np.angle(np.exp(1j * (run["q"][-1] - Q_UP))), run["v"][-1]])
    return 1.0 + float(np.max(np.abs(e))), c


def first_swingups(plant: Plant, horizon: float, knot_dt: float, periods: tuple = (0.3, 0.4, 0.5, 0.6, 0.8),
                   amplitudes: tuple = (0.5, 1.0),
                   weights: tuple = ((0.1, 0.0), (1.0, 0.0), (0.1, 0.1), (1.0, 1.0), (1.0, 0.03), (1.0, 0.07)),
                   w_T: float = 1e4) -> list[tuple[float, np.ndarray, dict]]:  # fmt: skip
    """Step 1 (module docstring): for each initial guess ``u = a u_max sin(2 pi t / period)`` and each iLQR weight
    pair ``(w_u, w_v)`` (effort; the rates' running weight; a rates' weight a few hundredths of the effort's is the
    score's own exchange rate near the leaders: the slope of ``tanh(pi c / n)`` makes a unit of torque cost worth about
    14 of velocity cost at the pendubot's leading values), the iLQR swing-up within ``horizon`` [s] on knots 0.01 s
    apart (:func:`mbs_envs.controllers.trajectory.ilqr`, terminal weight ``w_T``); those ending within 0.05 of upright
    fitted as a spline design (:func:`fit_knots`). Returns ``(objective, knots, settings)`` of each, best first."""
    plan_dt, H = 0.01, int(round(horizon / 0.01))
    stride = int(round(plan_dt / plant.dt))
    x0, goal = np.concatenate([Q_DOWN, np.zeros(2)]), np.concatenate([Q_UP, np.zeros(2)])
    P_T = w_T * np.diag([1.0, 1.0, 0.1, 0.1])
    t = np.arange(H) * plan_dt
    out = []
    for period in periods:
        for a in amplitudes:
            for w_u, w_v in weights:
                U = a * plant.u_max * np.sin(2 * np.pi * t / period)
                X = traj.ilqr(x0, U, np.zeros((H + 1, 4)), np.zeros((H, 4)), goal, w_u, np.diag([0.0, 0.0, w_v, w_v]), P_T,
                              plant.u_max, plant.driven, plant.theta, plan_dt, plant.substeps * stride, 200, traj.ALPHAS)[0]  # fmt: skip
                if np.max(np.abs(traj.wrapped(X[H], goal))) > 0.05:
                    continue
                z0 = np.interp(
                    np.arange(0.0, H * plan_dt + 1e-9, knot_dt), (np.arange(H + 1) + 0.5) * plan_dt, np.append(U, 0.0)
                )
                z0[-1] = 0.0
                z = fit_knots(plant, z0, knot_dt)
                settings = {"horizon": horizon, "period": period, "amplitude": a, "w_u": w_u, "w_v": w_v}
                out.append((design_score(plant, z, knot_dt)[0], z, settings))
    return sorted(out, key=lambda r: r[0])


def fit_knots(plant: Plant, knots: np.ndarray, knot_dt: float, evaluations: int = 200) -> np.ndarray:
    """Knots whose spline input ends the plan at upright: SciPy's ``least_squares`` (bounded by the torque limit) on
    the wrapped terminal error (weight 100) and the knots' differences (weight 0.03, a smoothness prior), from
    ``knots`` (an iLQR input on a finer grid, sampled at the knots, does not end at upright through the spline)."""
    goal = np.concatenate([Q_UP, np.zeros(2)])

    def residual(z: np.ndarray) -> np.ndarray:
        U = feedforward(z, knot_dt, plant.dt, plant.u_max)
        X = np.zeros((len(U) + 1, 4))
        X[0, :2] = Q_DOWN
        u = np.empty(len(U) + 1)
        closed_loop(
            U, plant.K, goal, plant.u_max, plant.driven, plant.theta, plant.dt, plant.substeps, len(U) + 1, X, u
        )
        return np.concatenate([100.0 * traj.wrapped(X[len(U)], goal), 0.03 * np.diff(z)])

    fit = least_squares(residual, np.clip(knots, -plant.u_max, plant.u_max), bounds=(-plant.u_max, plant.u_max),
                        max_nfev=evaluations)  # fmt: skip
    return np.asarray(fit.x)


def design(plant: Plant, horizons: tuple = (1.0, 1.2, 1.5), knot_dt: float = 0.05, top: int = 3,
           evaluations: int = 8000, seed: int = 0, progress: Any = None) -> tuple[np.ndarray, dict]:  # fmt: skip
    """Steps 1 and 2: the first swing-ups of every horizon, the ``top`` best searched (:func:`search`); returns the
    best knots and ``{"objective", "criteria", "settings", "candidates"}``."""
    firsts = []
    for h in horizons:
        firsts += first_swingups(plant, h, knot_dt)
        if progress is not None:
            progress(f"horizon {h}: {len(firsts)} first swing-ups")
    firsts.sort(key=lambda r: r[0])
    best = None
    for f0, z0, settings in firsts[:top]:
        z, f = search(plant, z0, knot_dt, evaluations, seed=seed)
        if progress is not None:
            progress(f"{settings}: {-f0:.4f} -> {-f:.4f}")
        if best is None or f < best[0]:
            best = (f, z, settings)
    f, z, settings = best
    return z, {"objective": f, "criteria": design_score(plant, z, knot_dt)[1], "settings": settings,
               "candidates": [{"objective": r[0], **r[2]} for r in firsts]}  # fmt: skip


def search(plant: Plant, knots: np.ndarray, knot_dt: float, evaluations: int = 5000, sigma: float = 0.3,
           seed: int = 0) -> tuple[np.ndarray, float]:  # fmt: skip
    """Step 2 (module docstring): a (1+1) evolution strategy on the objective of :func:`design_score` from
    ``knots``: a Gaussian step of ``sigma`` [N m] per knot, taken where it does not worsen the objective, ``sigma``
    adapted by the one-fifth rule (times 1.5 on a success, 1.5^(-1/4) otherwise; at least 1e-3 N m). Monotone (the
    result is never worse than the start) and reproducible from ``seed``. Returns ``(best knots, best objective)``."""
    rng = np.random.default_rng(seed)
    z = np.clip(np.asarray(knots, float), -plant.u_max, plant.u_max)
    f = design_score(plant, z, knot_dt)[0]
    for _ in range(evaluations):
        trial = np.clip(z + sigma * rng.standard_normal(len(z)), -plant.u_max, plant.u_max)
        ft = design_score(plant, trial, knot_dt)[0]
        if ft <= f:
            z, f = trial, ft
            sigma *= 1.5
        else:
            sigma = max(sigma * 1.5**-0.25, 1e-3)
    return z, f


def write_design(
    out: Any, env_id: str, knots: np.ndarray, info: dict, knot_dt: float, command: str | None = None
) -> dict:
    """``design.json`` (the knots, the criteria and score of the nominal rollout, the settings of the first swing-up
    it came from, every candidate's objective, and the ``command`` that made it where given) and ``design.png``
    (angles and torque of the rollout) to ``out``."""
    import json
    import pathlib

    from .plotting import pyplot, save

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = gym.make(env_id)
    plant = Plant.of(env)
    run = rollout(plant, knots, knot_dt)
    entry = {"env_id": env_id, "knot_dt": knot_dt, "knots": [round(float(x), 6) for x in knots],
             "criteria": info["criteria"], "settings": info["settings"], "candidates": info["candidates"]}  # fmt: skip
    if command is not None:
        entry["command"] = command
    (out / "design.json").write_text(json.dumps(entry, indent=1))
    plt = pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    n = int(3.0 / plant.dt)
    ax[0].plot(run["T"][:n], run["q"][:n])
    ax[0].set_ylabel("angles [rad]")
    ax[0].legend(["q1", "q2"])
    ax[1].plot(run["T"][:n], run["u"][:n, plant.driven])
    ax[1].set_ylabel("torque [N m]")
    ax[1].set_xlabel("t [s]")
    ax[0].set_title(f"{env_id}: score {info['criteria']['score']:.3f} (first 3 s of 10)")
    save(fig, out / "design.png")
    return entry


def plan_starts(env_id: str, share: float, stride: int = 10) -> dict[str, Any]:
    """Training starts along the score-designed swing-up: the ``start_states`` setting (a
    :class:`~mbs_envs.envs.swingup.StartBank` as JSON's form) of an env on the protocol's plant.

    Parameters
    ----------
    env_id : str
        A protocol or training id on the DFKI plant (its protocol id's shipped design is the plan).
    share : float
        The share, in [0, 1], of the episodes that would start hanging which start from the plan instead.
    stride : int
        Every ``stride``-th state of the plan (its control steps ``dt`` apart) is a row.

    Returns
    -------
    dict
        ``{"share": share, "rows": [[th1, th2, dth1, dth2], ...]}``: the nominal plan's states from hanging at rest to
        the hand-over to the upright LQR (:class:`~mbs_envs.controllers.scored_swingup.ScoredSwingUp`'s ``X``).
    """
    from .dfki_selection import protocol_id

    from .. import validation as check
    from ..controllers.scored_swingup import stored_design

    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
    share = check.real(share, "share", 0.0, 1.0)  # refused before the plan is built
    design = stored_design(protocol_id(env_id))
    X = ScoredSwingUp(gym.make(env_id), design=design).X[::stride]
    return {"share": share, "rows": [[round(float(x), 12) for x in row] for row in X]}


def designs_in(out: Any, robots: tuple = ("Acrobot", "Pendubot")) -> list[dict]:
    """The designs written to ``out`` (``<robot>/design.json`` of each robot that has one, in ``robots``' order), by one
    run of ``scripts/dfki_design.py`` or several: what its report covers."""
    import json
    import pathlib

    files = [pathlib.Path(out) / r / "design.json" for r in robots]
    return [json.loads(f.read_text()) for f in files if f.exists()]


def design_report(entries: list[dict]) -> str:
    """The designs' criteria beside the published simulation-v2 leader of each robot (markdown)."""
    from .dfki import PUBLISHED_SIMULATION_V2

    keys = ("swingup_time", "energy", "tau_cost", "tau_smoothness", "velocity_cost", "score")
    lines = []
    for e in entries:
        robot = e["env_id"].split("/")[-1].replace("DFKI-v1", "")
        c = e["criteria"]
        lines += [f"### {e['env_id']}", "",
                  "| | swing-up time [s] | energy [J] | torque cost | smoothness [N m] | velocity cost | score |",
                  "|---|---|---|---|---|---|---|",
                  "| **score-designed swing-up (nominal rollout)** | " + " | ".join(f"{c[k]:.4g}" for k in keys) + " |"]  # fmt: skip
        rows = PUBLISHED_SIMULATION_V2.get(robot, {}).get("rows", {})
        if rows:
            name, row = max(rows.items(), key=lambda kv: kv[1][-1])
            lines.append(f"| {name} (published leader) | " + " | ".join(f"{x:g}" for x in row) + " |")
            terms = [np.tanh(np.pi * c[k] / n) for k, n in dfki.NORMALIZERS.items()]
            theirs = [np.tanh(np.pi * x / n) for x, n in zip(row[:5], dfki.NORMALIZERS.values())]
            lines.append("| its terms tanh(pi c / n): ours | " + " | ".join(f"{x:.3f}" for x in terms) + " | |")
            lines.append(f"| its terms tanh(pi c / n): {name} | " + " | ".join(f"{x:.3f}" for x in theirs) + " | |")
        s = e["settings"]
        lines += ["", f"First swing-up: {s['horizon']} s horizon, sinusoid of period {s['period']} s at "
                  f"{s['amplitude']:g} of the limit, iLQR weights w_u = {s['w_u']:g}, w_v = {s['w_v']:g}; "
                  f"{len(e['knots'])} knots {e['knot_dt']} s apart."
                  + (f" Designed by `{e['command']}`." if e.get("command") else ""), "",
                  f"![{e['env_id']}]({robot}/design.png)", ""]  # fmt: skip
    return "\n".join(lines)
