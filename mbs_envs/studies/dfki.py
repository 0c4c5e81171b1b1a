"""The DFKI double-pendulum benchmark (RealAIGym) as the project computes it: success rule and score.

The protocol's plant and simulation are the preset ``"dfki_c1"`` (:mod:`mbs_envs.envs.presets`; the
ids ``mbs_envs/AcrobotDFKI-v1``, ``mbs_envs/PendubotDFKI-v1``). An episode is recorded as the
benchmark's simulator records one (``Simulator.step`` records before it integrates): at every control
step ``i`` the time ``T[i] = i dt``, the state ``X[i] = (q, v)`` the step starts from and the torques
``U[i]`` (both joints, the passive one 0, after the limit) it applies; ``N`` = 5,000 rows for 10 s.

**Success** (their ``get_swingup_time``, method ``"height"``, ``has_to_stay``): the end effector's
height over the shoulder, ``y = l1 sin q1 + l2 sin(q1 + q2)`` in our angles (upright at
``(pi/2, 0)``), is above ``0.9 (l1 + l2)`` from the swing-up time to the end. Their loop scans the
samples ``N-2, N-3, ..., 1`` backwards while the end effector is up: the swing-up time is the first
sample of the run of "up" samples that ends at ``N-2`` (the last sample is not read), and
``T[N-1]`` when sample ``N-2`` is down; the episode succeeds when that time is before ``T[N-1]``.

**Score** (simulation leaderboard v2): ``success * (1 - mean_k tanh(pi c_k / n_k))`` over five
criteria ``c_k`` with the leaderboard's normalizers ``n_k`` (:data:`NORMALIZERS`):

- swing-up time [s];
- energy ``sum_i sum_j |(q_j[i+1] - q_j[i]) u_j[i]|`` [J];
- torque cost ``sum_i |u[i]|^2 dt_i`` [N^2 m^2 s];
- torque smoothness ``sum_j std_i(u_j[i+1] - u_j[i])`` [N m] (over all ``N - 1`` differences);
- velocity cost ``sum_i |v[i]|^2 dt_i`` [rad^2/s].

Every sum runs over ``i = 0 .. N-2`` (the intervals). The functions take numpy arrays and are checked
in ``tests/test_dfki.py`` on hand-made trajectories and against the published leaderboard rows.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from ..envs.perturbations import PULSES, RANGES, RATE_INDEX  # noqa: F401  (the benchmark's robustness-v2 ranges)


#: end-effector threshold as a fraction of the reach ``l1 + l2``
HEIGHT = 0.9
#: simulation leaderboard v2: every criterion weighted 1, divided by these
NORMALIZERS: Mapping[str, float] = MappingProxyType(
    {"swingup_time": 20.0, "energy": 60.0, "tau_cost": 20.0, "tau_smoothness": 0.1, "velocity_cost": 400.0}
)


def end_effector_height(q: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """``y = l1 sin q1 + l2 sin(q1 + q2)`` [m], shape ``(...)``, from our angles ``q`` ``(..., 2)``."""
    q = np.asarray(q, float)
    return l1 * np.sin(q[..., 0]) + l2 * np.sin(q[..., 0] + q[..., 1])


def swingup_time(T: np.ndarray, up: np.ndarray) -> float:
    """The swing-up time [s] from the sample times ``T`` ``(N,)`` and whether the end effector is up ``(N,)``
    (module docstring: the start of the run of "up" samples ending at ``N-2``; ``T[-1]`` if none)."""
    T, up = np.asarray(T, float), np.asarray(up, bool)
    if T.ndim != 1 or T.shape != up.shape or len(T) < 3:
        raise ValueError(f"T and up must be 1-D of one length >= 3, got shapes {T.shape} and {up.shape}")
    index = len(T) - 1
    down = np.flatnonzero(~up[1:-1])  # samples 1 .. N-2
    first = (down[-1] + 2) if down.size else 1  # first "up" sample after the last "down" one
    if first <= len(T) - 2:
        index = first
    return float(T[index])


def criteria(T: np.ndarray, q: np.ndarray, v: np.ndarray, u: np.ndarray, l1: float, l2: float) -> dict[str, float]:
    """The benchmark's criteria of one episode (module docstring).

    Parameters
    ----------
    T : ndarray, shape (N,)
        Sample times [s], the start included.
    q, v : ndarray, shape (N, 2)
        Angles (ours: upright at ``(pi/2, 0)``; unwrapped or wrapped, steps are wrapped) [rad] and velocities [rad/s].
    u : ndarray, shape (N, 2)
        Torques on both joints [N m] applied from ``T[i]`` on.
    l1, l2 : float
        Link lengths [m] (the success threshold).

    Returns
    -------
    dict
        ``success`` (1.0 or 0.0), ``swingup_time``, ``energy``, ``tau_cost``, ``tau_smoothness``,
        ``velocity_cost``.
    """
    T, q, v, u = (np.asarray(x, float) for x in (T, q, v, u))
    n = len(T)
    if q.shape != (n, 2) or v.shape != (n, 2) or u.shape != (n, 2):
        raise ValueError(f"q, v and u must have shape ({n}, 2) for {n} times, got {q.shape}, {v.shape}, {u.shape}")
    dt = np.diff(T)
    dq = np.angle(np.exp(1j * np.diff(q, axis=0)))  # a step of the angle, wrapped (2 ms steps are far below pi)
    t_up = swingup_time(T, end_effector_height(q, l1, l2) > HEIGHT * (l1 + l2))
    return {
        "success": float(t_up < T[-1]),
        "swingup_time": t_up,
        "energy": float(np.abs(dq * u[:-1]).sum()),
        "tau_cost": float((u[:-1] ** 2 * dt[:, None]).sum()),
        "tau_smoothness": float(np.std(np.diff(u, axis=0), axis=0).sum()),
        "velocity_cost": float((v[:-1] ** 2 * dt[:, None]).sum()),
    }


def torque_use(T: np.ndarray, v: np.ndarray, u: np.ndarray, driven: int, t_end: float) -> dict[str, float]:
    """How much of a swing-up's torque cost does work: its cost against the least cost of the same work at the same
    rates of the driven joint.

    Over the intervals before ``t_end`` (the swing-up time; sums as in :func:`criteria`), with ``u_d, v_d`` the
    driven joint's torque and rate: the torque cost ``C = sum u_d^2 dt``, the work ``W = sum |u_d v_d| dt`` and
    ``V = sum v_d^2 dt``. By Cauchy-Schwarz ``W^2 <= C V``: for these rates no torque doing the work ``W`` costs
    less than ``W^2 / V``, and the torque reaches it only when ``|u_d|`` is proportional to ``|v_d|``. Torque held
    against a still joint costs and does no work.

    Parameters
    ----------
    T : ndarray, shape (N,)
        Sample times [s].
    v, u : ndarray, shape (N, 2)
        Rates [rad/s] and torques [N m], torque ``u[i]`` applied from ``T[i]`` on.
    driven : int
        The driven joint (0 or 1).
    t_end : float
        End of the window [s].

    Returns
    -------
    dict
        ``swingup_tau_cost`` (``C``), ``work`` (``W``, J), ``least_tau_cost`` (``W^2 / V``; 0 when ``V = 0``) and
        ``torque_use`` (``W^2 / (C V)`` in ``[0, 1]``; NaN without torque or without motion).
    """
    T, v, u = (np.asarray(x, float) for x in (T, v, u))
    if driven not in (0, 1):
        raise ValueError(f"driven must be 0 or 1, got {driven!r}")
    if v.shape != (len(T), 2) or u.shape != (len(T), 2):
        raise ValueError(f"v and u must have shape ({len(T)}, 2), got {v.shape} and {u.shape}")
    dt = np.diff(T)
    m = T[:-1] < t_end
    ud, vd, dt = u[:-1, driven][m], v[:-1, driven][m], dt[m]
    C, W, V = float((ud**2 * dt).sum()), float((np.abs(ud * vd) * dt).sum()), float((vd**2 * dt).sum())
    least = W * W / V if V > 0 else 0.0
    return {"swingup_tau_cost": C, "work": W, "least_tau_cost": least,
            "torque_use": least / C if C > 0 and V > 0 else float("nan")}  # fmt: skip


def score(c: Mapping[str, Any], normalizers: Mapping[str, float] = NORMALIZERS) -> float:
    """The leaderboard's score v2, ``success * (1 - mean_k tanh(pi c_k / n_k))``, in ``[0, 1]``."""
    terms = [np.tanh(np.pi * float(c[k]) / n) for k, n in normalizers.items()]
    return float(c["success"]) * (1.0 - float(np.mean(terms)))


def record(venv: Any, policy: Any, seeds: list[int], deterministic: bool = True) -> list[dict[str, Any]]:
    """Run one protocol episode per seed on a batched env and record it as the benchmark does.

    Parameters
    ----------
    venv : MBSVectorEnv
        Of a protocol id (``gym.make_vec("mbs_envs/AcrobotDFKI-v1", num_envs=len(seeds),
        vectorization_mode="vector_entry_point", autoreset_mode="Disabled")``).
    policy : object with ``predict``
        Called once per control step on the batch; its memory passed back through ``state``.
    seeds : list of int
        Member ``i`` resets with ``seeds[i]`` (the protocol starts at rest, so seeds matter only to
        a stochastic policy or a randomized plant).

    Returns
    -------
    list of dict
        Per member: ``T (N,)``, ``q (N, 2)``, ``v (N, 2)``, ``u (N, 2)`` (module docstring) and
        ``terminated`` (the episode ended early: diverged). The arrays stop at the member's last step.
    """
    base = venv.unwrapped
    n = len(seeds)
    if base.num_envs != n:
        raise ValueError(f"venv has {base.num_envs} members for {n} seeds")
    steps = base.max_episode_steps
    if steps is None:
        raise ValueError("venv needs a max_episode_steps (make it with gym.make_vec from a protocol id)")
    driven, dt = int(base.env.driven), float(base.env.dt)
    obs, _ = base.reset(seed=list(seeds))
    q, v, u = np.zeros((steps, n, 2)), np.zeros((steps, n, 2)), np.zeros((steps, n, 2))
    end = np.full(n, steps)
    done = np.zeros(n, bool)
    state, start = None, np.ones(n, bool)
    for i in range(steps):
        q[i], v[i] = base.q, base.v
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=deterministic)
        start = np.zeros(n, bool)
        obs, _, terminated, truncated, info = base.step(action)
        u[i, :, driven] = np.asarray(info["u"], float).reshape(n, -1)[:, 0]
        newly = ~done & (terminated | truncated)
        end[newly & terminated] = i + 1
        done |= newly
        if done.all():
            break
    T = np.arange(steps) * dt
    return [{"T": T[: end[k]], "q": q[: end[k], k], "v": v[: end[k], k], "u": u[: end[k], k], "terminated": bool(end[k] < steps)}
            for k in range(n)]  # fmt: skip


def evaluate(runs: list[dict[str, Any]], l1: float, l2: float) -> list[dict[str, float]]:
    """:func:`criteria` and :func:`score` of recorded runs; a run that ended early fails (score 0)."""
    out = []
    for run in runs:
        c = criteria(run["T"], run["q"], run["v"], run["u"], l1, l2) if len(run["T"]) >= 3 else {"success": 0.0}
        if run["terminated"]:
            c["success"] = 0.0
        c["score"] = score(c) if c["success"] else 0.0
        out.append(c)
    return out


# -- the robustness benchmark (robustness v2) ---------------------------------------------------------

#: values per swept axis (their ``N_var``)
N_VALUES = 21
#: the final-state rule: |wrapped angle error| and |velocity| below these (their ``eps``, ``check_only_final_state``)
FINAL_EPS = (0.35, 0.35, 1.0, 1.0)
#: the axes, in their order; the score is the mean of their success fractions
AXES = ("model", "velocity noise", "torque noise", "torque response", "time delay", "perturbations")
#: model axes varied by x [0.75, 1.25] in their convention (m r with m fixed, so r moves; I about the joint)
MODEL_FACTORS = ("m1r1", "I1", "m2r2", "m2", "I2")
#: viscous friction swept over [0, 0.1] N m s/rad (their range is [-0.1, 0.1]; ours is >= 0: the upper half)
MODEL_DAMPING = ("b1", "b2")


def final_success(q: np.ndarray, v: np.ndarray, eps: tuple = FINAL_EPS) -> np.ndarray:
    """Their final-state rule on our states ``q, v`` ``(n, 2)``: within ``eps`` of upright at rest, ``(n,)`` bool."""
    e = np.angle(np.exp(1j * (np.asarray(q, float) - np.array([np.pi / 2, 0.0]))))
    return (np.abs(e) < eps[:2]).all(-1) & (np.abs(np.asarray(v, float)) < eps[2:]).all(-1)


def run_success(res: Mapping[str, Any]) -> np.ndarray:
    """Per member of a perturbed batch (:func:`mbs_envs.studies.robustness.run`'s result): it ended by
    :func:`final_success` and did not diverge, ``(n,)`` bool."""
    return final_success(res["q"], res["v"]) & ~res["terminated"]


def model_variations(p: Any = None, n: int = N_VALUES, rng: np.random.Generator | None = None
                     ) -> list[tuple[str, float, dict[str, float] | None]]:  # fmt: skip
    """The model axis as ``(parameter, value, Planar2R params or None)``: their variations of ``p`` (default
    :data:`~mbs_envs.envs.presets.DFKI_C1`) converted with :func:`~mbs_envs.envs.presets.planar2r_params`;
    None where the variation has no rigid link (an inertia about the joint below ``m r^2``), which is not simulated.
    Left out: the motor inertia (Planar2R has no rotor), Coulomb friction (a differently smoothed law) and
    negative damping.

    With ``rng`` the values are drawn rather than spaced: per factor ``n`` factors ``U(0.75, 1.25)``, per damping
    ``(n + 1) // 2`` values ``U(0, 0.1)``, in that order (:func:`axis_values`)."""
    import dataclasses

    from ..envs.presets import DFKI_C1, planar2r_params

    p = DFKI_C1 if p is None else p
    out: list[tuple[str, float, dict[str, float] | None]] = []
    for name in MODEL_FACTORS:
        for f in axis_values((0.75, 1.25), n, rng):
            if name == "m1r1":
                value, changed = p.m1 * p.r1 * f, {"r1": p.r1 * f}
            elif name == "m2r2":
                value, changed = p.m2 * p.r2 * f, {"r2": p.r2 * f}
            else:
                value, changed = getattr(p, name) * f, {name: getattr(p, name) * f}
            try:
                params = planar2r_params(dataclasses.replace(p, **changed))
            except ValueError:
                params = None
            out.append((name, float(value), params))
    for name in MODEL_DAMPING:
        for value in axis_values((0.0, 0.1), (n + 1) // 2, rng):
            out.append((name, float(value), {**planar2r_params(p), name: float(value)}))
    return out


def axis_values(bounds: tuple[float, float], n: int, rng: np.random.Generator | None = None) -> np.ndarray:
    """``n`` values of an axis over ``bounds``: their grid (``linspace``) or, with ``rng``, uniform draws
    ``U(low, high)`` (a tuning set of the same ranges that shares no value with the grid but by chance), ``(n,)``."""
    return np.linspace(*bounds, n) if rng is None else rng.uniform(*bounds, n)


def random_pulses(rng: np.random.Generator, episodes: int, t: np.ndarray) -> np.ndarray:
    """Their random disturbance (``get_random_gauss_perturbation_array``): per episode ``2 k`` Gaussian torque
    pulses, ``k`` per joint, centres at least ``min_spacing`` apart in shuffled order, widths and heights
    uniform in :data:`PULSES` ranges with random signs (:func:`mbs_envs.studies.robustness.random_pulses`).
    Returns ``(episodes, len(t), 2)`` [N m]."""
    from .robustness import random_pulses as pulses

    return pulses(rng, episodes, t, 2, PULSES["per_joint"], PULSES["min_spacing"], PULSES["sigma"], PULSES["amplitude"])


@dataclasses.dataclass(frozen=True)
class SweepPart:
    """Members ``members`` of one axis' batch (:func:`sweep_parts`): what :func:`sweep_part` runs.

    Attributes
    ----------
    axis : str
    members : slice
        Rows of the axis' batch.
    size : int
        The axis' batch size.
    perturbation : Perturbation
        The whole batch's settings.
    noise_seed : int
        The batch's noise seed.
    member_params : list of dict, optional
        The whole batch's plant parameters (the model axis).
    """

    axis: str
    members: slice
    size: int
    perturbation: Any
    noise_seed: int
    member_params: list | None = None

    def cut(self, part_size: int) -> list[SweepPart]:
        """These members in parts of at most ``part_size`` (an integer >= 1), in order."""
        a, b = self.members.start, self.members.stop
        return [dataclasses.replace(self, members=slice(k, min(k + part_size, b))) for k in range(a, b, part_size)]


def sweep_parts(env_id: str, n: int = N_VALUES, seed: int = 0, axes: tuple = AXES, part_size: int | None = None,
                draw_seed: int | None = None) -> tuple[list[SweepPart], dict[str, dict[str, Any]]]:  # fmt: skip
    """The robustness benchmark of a protocol id as parts of at most ``part_size`` members (None: one part per axis),
    and each axis' description (``values``; the model axis' ``skipped``). The noise seeds and pulses are drawn from
    ``seed`` in the axes' order, so the parts of any size give one sweep's episodes (:func:`robustness.run`'s ``batch``).
    With ``draw_seed`` the swept values are drawn uniformly over the axes' ranges from that seed instead of their grid
    (:func:`axis_values`; ``n`` per axis as there, pulses as ever from ``seed``): a tuning set beside the benchmark."""
    import gymnasium as gym

    from .robustness import Perturbation

    from .. import validation as check

    part_size = None if part_size is None else check.integer(part_size, "part_size", 1, 10**9)
    nominal = gym.make(env_id)
    steps, dt = nominal.spec.max_episode_steps, float(nominal.unwrapped.dt)
    rng = np.random.default_rng(seed)
    draws = None if draw_seed is None else np.random.default_rng(draw_seed)
    parts: list[SweepPart] = []
    meta: dict[str, dict[str, Any]] = {}
    for axis in axes:
        params = None
        if axis == "model":
            points = model_variations(n=n, rng=draws)
            kept = [(name, value, q) for name, value, q in points if q is not None]
            size, p, params = len(kept), Perturbation(), [q for _, _, q in kept]
            meta[axis] = {"values": [(name, value) for name, value, _ in kept],
                          "skipped": [(name, value) for name, value, q in points if q is None]}  # fmt: skip
        elif axis == "perturbations":
            size = PULSES["episodes"]
            p = Perturbation(pulses=random_pulses(rng, size, np.arange(steps) * dt))
            meta[axis] = {"values": list(range(size))}
        else:
            values = axis_values(RANGES[axis], n, draws)
            size = n
            p = {"velocity noise": lambda x: Perturbation(noise_sigma=x, noise_index=RATE_INDEX),
                 "torque noise": lambda x: Perturbation(torque_sigma=x),
                 "torque response": lambda x: Perturbation(response=x),
                 "time delay": lambda x: Perturbation(delay=np.rint(x / dt).astype(int))}[axis](values)  # fmt: skip
            meta[axis] = {"values": values.tolist()}
        whole = SweepPart(axis, slice(0, size), size, p, int(rng.integers(2**31)), params)
        parts += [whole] if part_size is None else whole.cut(part_size)
    return parts, meta


def sweep_part(env_id: str, make_policy: Any, part: SweepPart) -> np.ndarray:
    """Run one :class:`SweepPart`: its members' success (bool per member), ``make_policy(env)`` on the nominal env."""
    import gymnasium as gym

    from .robustness import run

    m = part.members
    kwargs = {} if part.member_params is None else {"member_params": part.member_params[m]}
    count = m.stop - m.start
    venv = gym.make_vec(
        env_id, num_envs=count, vectorization_mode="vector_entry_point", autoreset_mode="Disabled", **kwargs
    )
    try:
        res = run(venv, make_policy(gym.make(env_id)), list(range(m.start, m.stop)), part.perturbation.rows(m),
                  noise_seed=part.noise_seed, batch=(part.size, m.start))  # fmt: skip
    finally:
        venv.close()
    return run_success(res)


def assemble_sweep(
    meta: Mapping[str, Mapping[str, Any]], parts: list[SweepPart], success: list[np.ndarray]
) -> dict[str, dict[str, Any]]:
    """The sweep's result (:func:`sweep`) from its parts' successes (any order of parts)."""
    out: dict[str, dict[str, Any]] = {}
    for axis, info in meta.items():
        mine = sorted(
            ((p.members.start, p.size, ok) for p, ok in zip(parts, success) if p.axis == axis), key=lambda t: t[0]
        )
        ok = np.concatenate([o for _, _, o in mine]) if mine else np.empty(0)
        if (
            not mine
            or len(ok) != mine[0][1]
            or [a for a, _, _ in mine] != list(np.cumsum([0] + [len(o) for _, _, o in mine[:-1]]))
        ):
            raise ValueError(f"the parts of axis {axis!r} do not make up its batch once")
        out[axis] = {**info, "success": ok, "fraction": float(np.mean(ok))}
    out["score"] = {"value": float(np.mean([out[a]["fraction"] for a in meta]))}
    return out


def sweep(env_id: str, make_policy: Any, n: int = N_VALUES, seed: int = 0, axes: tuple = AXES, progress: bool = False,
          part_size: int | None = None, draw_seed: int | None = None) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The robustness benchmark of one controller on a protocol id, one batched rollout per axis (or per part of
    ``part_size`` members; the same episodes: :func:`sweep_parts`), in this process.

    Parameters
    ----------
    env_id : str
        ``"mbs_envs/AcrobotDFKI-v1"`` or ``"mbs_envs/PendubotDFKI-v1"``.
    make_policy : callable
        ``make_policy(env) -> policy`` on the nominal env (called once per part; its memory lives in ``state``).
    n : int
        Values per axis (their 21).
    seed : int
        Seeds the noise and the random pulses.
    progress : bool
        Show a progress bar over the parts (tqdm, where installed): for a sweep run on its own, not in a pool whose
        own bar counts the jobs.
    draw_seed : int, optional
        Draw the axes' values from this seed instead of their grid (:func:`sweep_parts`).

    Returns
    -------
    dict
        Per axis: ``values`` (what each member varied; the model axis: ``(parameter, value)``), ``success``
        (bool per member; the model axis' unphysical variations are left out and counted in ``skipped``),
        ``fraction``; and ``"score"``: the mean of the fractions.
    """
    from .parallel import progress_bar

    parts, meta = sweep_parts(env_id, n, seed, axes, part_size, draw_seed)
    bar = progress_bar(len(parts), f"{env_id.split('/')[-1]} robustness" if progress else None)
    success = []
    for part in parts:
        if bar is not None:
            bar.set_postfix_str(part.axis)
        success.append(sweep_part(env_id, make_policy, part))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return assemble_sweep(meta, parts, success)


# -- the published leaderboards (real_ai_gym_leaderboard, 2024-09-03 release), to print our numbers beside -----------------------------

#: simulation performance v2: controller -> (swing-up time, energy, torque cost, smoothness, velocity cost, score)
PUBLISHED_SIMULATION_V2 = MappingProxyType({
    "Acrobot": MappingProxyType({
        "url": "https://dfki-ric-underactuated-lab.github.io/real_ai_gym_leaderboard/acrobot_simulation_performance_leaderboard_v2.html",
        "rows": MappingProxyType({
            "mcpilco": (1.45, 19.43, 3.22, 0.097, 253.59, 0.316),
            "History SAC": (1.0, 8.08, 1.8, 0.01, 88.5, 0.655),
            "TVLQR": (4.05, 10.43, 1.87, 0.016, 105.83, 0.504),
            "AR-EAPO": (1.39, 8.32, 1.52, 0.008, 117.96, 0.633),
            "iLQR Riccati Gains": (4.04, 10.55, 1.98, 0.067, 106.49, 0.396),
            "evolsac": (0.96, 9.26, 2.71, 0.03, 96.56, 0.524),
            "iLQR MPC stabilization": (4.86, 11.54, 2.68, 0.096, 110.4, 0.345),
        }),
    }),
    "Pendubot": MappingProxyType({
        "url": "https://dfki-ric-underactuated-lab.github.io/real_ai_gym_leaderboard/pendubot_simulation_performance_leaderboard_v2.html",
        "rows": MappingProxyType({
            "History SAC": (1.15, 7.67, 2.36, 0.007, 62.07, 0.682),
        }),
    }),
})  # fmt: skip

#: robustness v2: controller -> success fractions [%] of the six axes (AXES order) and the score
PUBLISHED_ROBUSTNESS_V2 = MappingProxyType({
    "Acrobot": MappingProxyType({
        "url": "https://dfki-ric-underactuated-lab.github.io/real_ai_gym_leaderboard/acrobot_simulation_robustness_leaderboard_v2.html",
        "rows": MappingProxyType({
            "mcpilco": (9.0, 9.5, 19.0, 52.4, 4.8, 50.0, 0.241),
            "History SAC": (58.1, 23.8, 100.0, 100.0, 90.5, 78.0, 0.751),
            "TVLQR": (48.1, 19.0, 100.0, 95.2, 23.8, 78.0, 0.607),
            "AR-EAPO": (67.6, 28.6, 100.0, 100.0, 76.2, 64.0, 0.727),
            "iLQR Riccati Gains": (4.8, 9.5, 9.5, 52.4, 4.8, 2.0, 0.138),
            "evolsac": (64.8, 23.8, 100.0, 100.0, 47.6, 76.0, 0.687),
            "iLQR MPC stabilization": (6.7, 9.5, 90.5, 52.4, 4.8, 42.0, 0.343),
        }),
    }),
    "Pendubot": MappingProxyType({
        "url": "https://dfki-ric-underactuated-lab.github.io/real_ai_gym_leaderboard/pendubot_simulation_robustness_leaderboard_v2.html",
        "rows": MappingProxyType({
            "mcpilco": (24.8, 76.2, 61.9, 95.2, 28.6, 82.0, 0.614),
            "History SAC": (68.1, 47.6, 100.0, 100.0, 100.0, 46.0, 0.770),
            "AR-EAPO": (87.6, 81.0, 100.0, 100.0, 81.0, 98.0, 0.913),
            "iLQR Riccati Gains": (5.2, 38.1, 9.5, 85.7, 14.3, 0.0, 0.255),
            "evolsac": (75.2, 57.1, 100.0, 100.0, 71.4, 68.0, 0.786),
            "TVLQR": (62.9, 90.5, 100.0, 100.0, 42.9, 64.0, 0.767),
            "iLQR MPC stabilization": (31.9, 90.5, 100.0, 100.0, 38.1, 44.0, 0.674),
        }),
    }),
})  # fmt: skip


#: the published entries whose policy is a network trained by model-free RL alone (mcpilco learns a model to search
#: its policy on; the rest are model-based controllers)
PUBLISHED_PURE_RL = ("History SAC", "AR-EAPO", "evolsac")


def controller_job(task: Mapping[str, Any]) -> dict[str, Any]:
    """One controller on one protocol id, or one part of its robustness sweep (a picklable task for
    :func:`mbs_envs.studies.parallel.run_tasks`).

    ``task``: ``env_id``, ``spec`` (``"module:Class"``, an agent folder or ``"lqr-catch:" + folder``, as
    :func:`mbs_envs.studies.comparison.load_policy` reads them), ``gains`` (a controller's entry of
    ``controllers/tuned.json`` or None), optionally ``rates_from_angles`` (True: the policy sees the joint rates
    differenced from the observed angles, :class:`controllers.estimator.RatesFromAngles`), optionally ``catch_gains``
    (the catching LQR's ``lqr_r``, ``catch`` and/or ``release`` in place of the tuned ones: on a controller's gains or on an
    RL + LQR pair, :func:`mbs_envs.studies.handover.hand_over`), and ``part`` (a :class:`SweepPart`: returns its ``success`` and ``wall_s``)
    or not (the protocol's episode: returns the recorded run, its criteria and score and ``wall_s``). Wall times in
    seconds.
    """
    import time

    import gymnasium as gym

    from .comparison import load_policy
    from .evaluation import make_controller

    over = dict(task.get("catch_gains") or {})
    if set(over) - {"lqr_r", "catch", "release"}:
        raise ValueError(f"catch_gains: unknown keys {sorted(set(over) - {'lqr_r', 'catch', 'release'})}")

    def make(env: Any) -> Any:
        if task.get("gains") is not None:
            policy = make_controller(task["spec"], env, {**task["gains"], **over})
        else:  # a controller with its defaults, an agent, or an agent + LQR (with the catch given, where given)
            policy = load_policy(task["spec"], env, over)
        if task.get("rates_from_angles"):
            from mbs_envs.controllers.estimator import RatesFromAngles

            policy = RatesFromAngles(policy, env)
        return policy

    tic = time.perf_counter()
    if task.get("part") is not None:
        return {"success": sweep_part(task["env_id"], make, task["part"]), "wall_s": time.perf_counter() - tic}
    run_, criteria_ = protocol_episode(task["env_id"], make(gym.make(task["env_id"])))
    return {"run": run_, "criteria": criteria_, "wall_s": time.perf_counter() - tic}


def protocol_episode(env_id: str, policy: Any) -> tuple[dict[str, Any], dict[str, float]]:
    """``policy``'s episode on the protocol id ``env_id`` (from its one start, seed 0), recorded as the benchmark
    records it (:func:`record`), and its criteria and score (:func:`evaluate`)."""
    import gymnasium as gym

    p = gym.make(env_id).unwrapped.model.params
    venv = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    run_ = record(venv, policy, [0])[0]
    venv.close()
    return run_, evaluate([run_], p.l1, p.l2)[0]
