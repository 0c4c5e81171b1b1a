"""Roll out any ``predict()`` policy (a controller or an SB3 agent) and measure it.

The same code scores model-based controllers and RL agents: both implement
``predict(obs, deterministic=True) -> (action, state)``.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import gymnasium as gym
import numpy as np


def controller_class(spec: str) -> Any:
    """The class named ``"module:Class"`` (e.g. ``"mbs_envs.controllers:LQR"``).

    Raises
    ------
    ValueError
        If ``spec`` is not of that form or names nothing importable.
    """
    import importlib

    if not (isinstance(spec, str) and spec.count(":") == 1 and all(spec.split(":"))):
        raise ValueError(f"a controller is named 'module:Class', got {spec!r}")
    module, cls = spec.split(":")
    try:
        return getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError):
        raise ValueError(f"no controller {spec!r}") from None


def controller_kwargs(spec: str, env: gym.Env, entry: dict[str, Any]) -> dict[str, Any]:
    """Constructor arguments of the controller ``spec`` for a gains ``entry`` of ``controllers/tuned.json``
    (a bandwidth ``{"omega", "zeta"}`` becomes ``kp, kd``; other entries are the arguments)."""
    if "omega" in entry:
        kp, kd = controller_class(spec).gains_from_bandwidth(env, entry["omega"], entry["zeta"])
        return {"kp": kp, "kd": kd}
    return dict(entry)


def make_controller(spec: str, env: gym.Env, gains: dict[str, Any] | None = None) -> Any:
    """The controller ``spec`` (``"module:Class"``) built on ``env``, with its default gains or ``gains``
    (an entry of ``controllers/tuned.json``)."""
    cls = controller_class(spec)
    return cls(env) if gains is None else cls(env, **controller_kwargs(spec, env, gains))


def default_gains_entry(spec: str, env: gym.Env) -> dict[str, Any] | None:
    """The tuned-gains entry ``spec`` takes by default on ``env`` (None for a controller without gains)."""
    from mbs_envs.controllers.tuned import tuned_gains

    name = getattr(controller_class(spec), "tuned_name", None)
    return None if name is None else tuned_gains(env, name)


@dataclasses.dataclass(frozen=True)
class Episode:
    """One recorded episode; arrays have one row per control step.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Time after each step [s].
    tracking_error : ndarray, shape (T, n)
        ``wrap(q_ref - q)`` after each step [rad].
    u : ndarray, shape (T, nu)
        Applied (saturated) inputs [N m].
    reward : ndarray, shape (T,)
    compute_time : ndarray, shape (T,)
        Wall time of each ``predict`` call [s].
    diverged : bool
    terminated : bool
    upright : ndarray of bool, shape (T,), optional
        Within the upright tolerance after each step (swing-up scenes' ``info["upright"]``).
    power : ndarray, shape (T,), optional
        The motor's mechanical power after each step [W] (swing-up scenes' ``info["power"]``).
    """

    t: np.ndarray
    tracking_error: np.ndarray
    u: np.ndarray
    reward: np.ndarray
    compute_time: np.ndarray
    diverged: bool
    terminated: bool
    upright: np.ndarray | None = None
    power: np.ndarray | None = None


def rollout(env: gym.Env, policy: Any, seed: int, deterministic: bool = True) -> Episode:
    """Run one episode of ``policy`` on ``env`` from ``reset(seed=seed)``."""
    obs, _ = env.reset(seed=seed)
    rows: dict[str, list] = {"t": [], "e": [], "u": [], "r": [], "dt": [], "upright": [], "power": []}
    state = None
    start = np.ones((1,), dtype=bool)
    while True:
        tic = time.perf_counter()
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=deterministic)
        rows["dt"].append(time.perf_counter() - tic)
        start = np.zeros((1,), dtype=bool)
        obs, reward, terminated, truncated, info = env.step(action)
        rows["t"].append(info["t"])
        rows["e"].append(info["tracking_error"])
        rows["u"].append(info["u"])
        rows["r"].append(reward)
        for key in ("upright", "power"):
            if key in info:
                rows[key].append(info[key])
        if terminated or truncated:
            break
    return Episode(
        t=np.array(rows["t"]),
        tracking_error=np.array(rows["e"]),
        u=np.array(rows["u"]),
        reward=np.array(rows["r"]),
        compute_time=np.array(rows["dt"]),
        diverged=bool(info["diverged"]),
        terminated=bool(terminated),
        upright=np.array(rows["upright"], bool) if rows["upright"] else None,
        power=np.array(rows["power"], float) if rows["power"] else None,
    )


def episode_metrics(ep: Episode, settle_time: float = 1.0) -> dict[str, float]:
    """Summary figures of an episode.

    ``rms_error`` is over the whole episode (so it includes the start
    transient); ``rms_error_settled`` only over ``t >= settle_time``, the
    tracking accuracy once the start error has decayed. Errors are the
    Euclidean norm over joints [rad]; torques the RMS/peak over joints and time.
    """
    err = np.linalg.norm(ep.tracking_error, axis=-1)
    settled = err[ep.t >= settle_time]
    return {
        "return": float(np.sum(ep.reward)),
        "rms_error": float(np.sqrt(np.mean(err**2))),
        "rms_error_settled": float(np.sqrt(np.mean(settled**2))) if settled.size else float("nan"),
        "max_error": float(np.max(err)),
        "rms_torque": float(np.sqrt(np.mean(ep.u**2))),
        "peak_torque": float(np.max(np.abs(ep.u))),
        "compute_us_per_action": float(np.median(ep.compute_time) * 1e6),
        "steps": int(len(ep.t)),
        "diverged": bool(ep.diverged),
    }


#: the looser success tolerance [rad] and the "near upright" band [rad] a swing-up is also scored at
WIDE_TOLERANCE, NEAR_UPRIGHT = 0.2, 0.3
#: [s] a swing-up succeeds when it stays upright for the last HOLD seconds of its episode
HOLD = 2.0


def swing_up_metrics(ep: Episode, hold: float = HOLD, dt: float | None = None) -> dict[str, float]:
    """Summary figures of a swing-up episode (Acrobot, Pendubot: v0 and v1), with those of :func:`episode_metrics`.

    - ``success``: within the upright tolerance at every step of the last ``hold`` seconds
      of a whole (not terminated) episode;
    - ``time_to_swing_up`` [s]: the time from which the arm stays upright to the end
      (NaN unless successful);
    - ``energy_used`` [J]: ``int |P| dt``, the motor's mechanical work whether it feeds
      energy in or takes it out (``P = u v_driven``, rectangle rule on the control steps);
    - ``success_wide``: as ``success`` with both joints within :data:`WIDE_TOLERANCE` (0.2 rad)
      of upright (from ``tracking_error``, the distance to upright);
    - ``time_near_upright`` [s]: the time with both joints within :data:`NEAR_UPRIGHT` (0.3 rad),
      wherever in the episode (a swing through upright counts its steps there).

    Parameters
    ----------
    ep : Episode
        With ``upright`` and ``power``.
    hold : float
        [s].
    dt : float, optional
        Control step [s] (default from ``ep.t``).
    """
    if ep.upright is None or ep.power is None:
        raise ValueError("a swing-up episode needs info['upright'] and info['power'] (Acrobot, Pendubot: v0 and v1)")
    out = episode_metrics(ep)
    dt = float(ep.t[1] - ep.t[0]) if dt is None and len(ep.t) > 1 else (dt or 0.0)
    last = ep.t >= ep.t[-1] - hold + 0.5 * dt if len(ep.t) else np.zeros(0, bool)
    success = bool(len(ep.t) and not ep.terminated and np.all(ep.upright[last]))
    time_up = float("nan")
    if success:
        down = np.flatnonzero(~ep.upright)
        time_up = float(ep.t[down[-1]]) if len(down) else 0.0  # from the step after the last one outside
    dist = np.max(np.abs(ep.tracking_error), axis=-1) if len(ep.t) else np.zeros(0)
    wide = bool(len(ep.t) and not ep.terminated and np.all(dist[last] <= WIDE_TOLERANCE))
    out.update(
        {
            "success": success,
            "time_to_swing_up": time_up,
            "energy_used": float(np.sum(np.abs(ep.power)) * dt),
            "success_wide": wide,
            "time_near_upright": float(np.sum(dist <= NEAR_UPRIGHT) * dt),
        }
    )
    return out


def tracking_score(ep: Episode) -> tuple[dict[str, float], bool]:
    """:func:`episode_metrics`, and whether the episode failed (it ended early)."""
    return episode_metrics(ep), bool(ep.terminated)


def swing_up_score(ep: Episode) -> tuple[dict[str, float], bool]:
    """:func:`swing_up_metrics`, and whether the episode failed (it did not end upright)."""
    m = swing_up_metrics(ep)
    return m, not m["success"]


#: how an episode is scored, by the scene registry's ``scoring``: metrics, and whether it failed
SCORING = {"tracking": tracking_score, "swing-up": swing_up_score}


#: the error a scene's episodes are ranked by (among those that did not fail), by ``scoring``
ERROR_METRIC = {"tracking": "rms_error_settled", "swing-up": "time_to_swing_up"}


def rollout_batch(
    venv: Any,
    policy: Any,
    seeds: list[int],
    deterministic: bool = True,
    obs_noise: float = 0.0,
    noise_seed: int = 0,
    delay: int = 0,
) -> list[Episode]:
    """One episode per seed, all at once on a batched vector env.

    Parameters
    ----------
    venv : MBSVectorEnv
        With ``num_envs == len(seeds)``, ``autoreset_mode=DISABLED`` and a
        ``max_episode_steps`` (``gym.make_vec(..., autoreset_mode="Disabled")``);
        ``full_info`` (the default) so ``info`` has the tracking error and ``u``.
    policy : object with ``predict``
        Called once per step on the whole batch of observations.
    seeds : list of int
        Member ``i`` starts from ``reset(seed=seeds[i])``, the same start as
        ``rollout(gym.make(id), policy, seeds[i])``.
    obs_noise : float
        Standard deviation of Gaussian noise added to every observation entry
        the policy sees (the environment's state is untouched).
    noise_seed : int
    delay : int
        Input delay in control steps: the plant applies the action the policy chose
        ``delay`` steps earlier (zero actions before that); the policy is unchanged.

    Returns
    -------
    list of Episode
        One per seed, each cut at its own end (termination or truncation).
        ``compute_time`` is the batch's ``predict`` time divided by the batch size.
    """
    venv = venv.unwrapped
    n = len(seeds)
    if venv.num_envs != n:
        raise ValueError(f"venv has {venv.num_envs} members for {n} seeds")
    obs, _ = venv.reset(seed=list(seeds))
    rng = np.random.default_rng(noise_seed)
    rows: dict[str, list] = {"t": [], "e": [], "u": [], "r": [], "dt": [], "div": [], "upright": [], "power": []}
    done = np.zeros(n, bool)
    end = np.zeros(n, int)
    terminated_any = np.zeros(n, bool)
    state = None
    start = np.ones(n, dtype=bool)
    if not (isinstance(delay, (int, np.integer)) and delay >= 0):
        raise ValueError(f"delay must be a whole number of control steps >= 0, got {delay!r}")
    queue = [np.zeros(venv.action_space.shape, venv.action_space.dtype)] * int(delay)
    while not done.all():
        seen = obs + rng.normal(0.0, obs_noise, obs.shape).astype(obs.dtype) if obs_noise > 0 else obs
        tic = time.perf_counter()
        action, state = policy.predict(seen, state=state, episode_start=start, deterministic=deterministic)
        rows["dt"].append((time.perf_counter() - tic) / n)
        start = np.zeros(n, dtype=bool)
        if delay:
            queue.append(action)
            action = queue.pop(0)
        obs, reward, terminated, truncated, info = venv.step(action)
        record_step(rows, reward, info)
        newly = ~done & (terminated | truncated)
        end[newly] = len(rows["t"])
        terminated_any |= newly & terminated
        done |= newly
    return episodes_from_rows(rows, end, terminated_any)


def record_step(rows: dict[str, list], reward: np.ndarray, info: dict[str, Any]) -> None:
    """Append one batched step's reward and ``info`` to ``rows`` (the keys :func:`episodes_from_rows` reads)."""
    rows["t"].append(info["t"])
    rows["e"].append(info["tracking_error"])
    rows["u"].append(info["u"])
    rows["r"].append(reward)
    rows["div"].append(info["diverged"])
    for key in ("upright", "power"):
        if key in info:
            rows.setdefault(key, []).append(info[key])


def episodes_from_rows(rows: dict[str, list], end: np.ndarray, terminated: np.ndarray) -> list[Episode]:
    """Cut a batched rollout's per-step records into one :class:`Episode` per member.

    Parameters
    ----------
    rows : dict of list
        Per control step, one entry with a value per member: ``t``, ``e`` (tracking error), ``u``, ``r``
        (reward), ``div`` (diverged) and, where the scene has them, ``upright`` and ``power``; ``dt``
        (compute time per member of the step's ``predict``) one scalar per step.
    end : ndarray of int (n,)
        Steps member ``i`` ran (its episode is the first ``end[i]`` rows).
    terminated : ndarray of bool (n,)
        Whether member ``i`` ended early.
    """
    t, e, u, r = (np.array(rows[k]) for k in ("t", "e", "u", "r"))
    div = np.array(rows["div"])
    dt = np.array(rows["dt"])
    up = np.array(rows["upright"], bool) if rows.get("upright") else None
    power = np.array(rows["power"], float) if rows.get("power") else None
    return [
        Episode(
            t=t[: end[i], i],
            tracking_error=e[: end[i], i],
            u=u[: end[i], i],
            reward=r[: end[i], i],
            compute_time=dt[: end[i]],
            diverged=bool(div[end[i] - 1, i]),
            terminated=bool(terminated[i]),
            upright=None if up is None else up[: end[i], i],
            power=None if power is None else power[: end[i], i],
        )
        for i in range(len(end))
    ]
