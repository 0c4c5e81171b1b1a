"""Soak runs, determinism across vectorizations, and parameters at the edges
(the logic of ``scripts/soak.py``; figures in ``docs/reliability.md``).
"""

from __future__ import annotations

import math
import signal
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.registry import SCENES, load
from ..dynamics.simulate import simulate


def random_episodes(env_id: str, episodes: int, num_envs: int = 256, seed: int = 0, wild_fraction: float = 0.1,
                    step_bound_s: int | None = None, **kwargs: Any) -> dict:  # fmt: skip
    """Random-action episodes on the batched env until ``episodes`` have ended.

    Actions are uniform in ``[-1, 1]``; a ``wild_fraction`` of them are
    out of range (up to 1e6, saturating). Counts every step's non-finite
    observations and rewards, divergences reported in ``info``, and episode ends.
    With ``step_bound_s``, a single batched step taking longer raises
    :class:`StepTimeout` (SIGALRM, main thread only): a hang.
    """
    import time

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False, **kwargs)
    old_handler = signal.signal(signal.SIGALRM, _alarm) if step_bound_s else None
    slowest = 0.0
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    ended = steps = nonfinite_obs = nonfinite_reward = diverged = terminated_n = 0
    max_abs_obs = float(np.max(np.abs(obs)))
    prev_done = np.zeros(num_envs, bool)
    while ended < episodes:
        a = rng.uniform(-1, 1, venv.action_space.shape)
        wild = rng.random(num_envs) < wild_fraction
        a[wild] *= 1e6
        if step_bound_s:
            signal.alarm(step_bound_s)
        t0 = time.perf_counter()
        try:
            obs, reward, term, trunc, info = venv.step(a)
        finally:
            if step_bound_s:
                signal.alarm(0)
        slowest = max(slowest, time.perf_counter() - t0)
        live = ~prev_done  # members whose step was a real step (not an autoreset)
        steps += int(live.sum())
        nonfinite_obs += int(np.sum(~np.all(np.isfinite(obs), axis=-1)))
        nonfinite_reward += int(np.sum(~np.isfinite(reward)))
        diverged += int(np.sum(info["diverged"] & live))
        terminated_n += int(np.sum(term & live))
        done = (term | trunc) & live
        ended += int(done.sum())
        prev_done = done
        max_abs_obs = max(max_abs_obs, float(np.max(np.abs(np.where(np.isfinite(obs), obs, 0.0)))))
    venv.close()
    if step_bound_s:
        signal.signal(signal.SIGALRM, old_handler)
    return {"env_id": env_id, "episodes": ended, "slowest_step_s": slowest, "steps": steps, "nonfinite_observations": nonfinite_obs,
            "nonfinite_rewards": nonfinite_reward, "divergences_reported": diverged, "terminations": terminated_n,
            "max_abs_observation": max_abs_obs}  # fmt: skip


class StepTimeout(Exception):
    """A step exceeded the soak's wall-clock bound (counted as a hang)."""


def _alarm(*_: Any) -> None:
    raise StepTimeout


def integrator_soak(env_id: str, integrator: str, episodes: int = 32, num_envs: int = 16, episode_steps: int = 100,
                    runaway_episodes: int = 4, hang_s: int = 60, seed: int = 0) -> dict:  # fmt: skip
    """Random-action episodes, then runaway episodes, of one id under one integrator.

    1. ``episodes`` random-action episodes of ``episode_steps`` steps on the
       batched env (10 % of actions out of range, up to 1e6), as
       :func:`random_episodes`, counting exceptions as well.
    2. ``runaway_episodes`` single-env episodes with a 1e200 N m torque limit and
       random full-scale actions until the step that diverges: whether it was
       flagged, non-finite outputs, exceptions, and the wall time of the
       diverging step (the first step of the first episode is a warm-up: it
       may compile kernels).

    A single step taking longer than ``hang_s`` seconds counts as a hang
    (SIGALRM, main thread only), in both parts.

    Returns
    -------
    dict
        ``steps, episodes, nonfinite, exceptions, hangs, divergences_reported``
        for the random part; ``runaway_*`` for the runaway part, with
        ``runaway_worst_step_s``, the slowest diverging step.
    """
    import time

    out = {"env_id": env_id, "integrator": integrator, "num_envs": num_envs, "episode_steps": episode_steps,
           "exceptions": 0, "hangs": 0, "nonfinite": 0, "errors": []}  # fmt: skip
    old = signal.signal(signal.SIGALRM, _alarm)

    def guarded(fn: Any, bound: int | None = hang_s) -> Any:
        if bound:
            signal.alarm(bound)
        try:
            return fn()
        except StepTimeout:
            out["hangs"] += 1
        except Exception as err:  # noqa: BLE001 - counted and reported: the target is none
            out["exceptions"] += 1
            out["errors"].append(f"{type(err).__name__}: {err}"[:200])
        finally:
            signal.alarm(0)
        return None

    try:
        r = guarded(bound=None, fn=lambda: random_episodes(env_id, episodes, num_envs=num_envs, seed=seed, integrator=integrator,
                                            max_episode_steps=episode_steps, step_bound_s=hang_s))  # fmt: skip
        r = r or {}
        out.update(
            {k: r.get(k, 0) for k in ("episodes", "steps", "divergences_reported", "terminations", "slowest_step_s")}
        )
        out["nonfinite"] += r.get("nonfinite_observations", 0) + r.get("nonfinite_rewards", 0)
        rng = np.random.default_rng(seed)
        env = gym.make(env_id, integrator=integrator, torque_limit=1e200)
        out.update(runaway_episodes=0, runaway_flagged=0, runaway_steps=0, runaway_worst_step_s=0.0)
        for k in range(runaway_episodes):
            if guarded(lambda: env.reset(seed=seed + k)) is None:
                continue
            if k == 0:
                guarded(lambda: env.step(np.zeros(env.action_space.shape)))  # warm-up (compilation)
            for _ in range(200):
                a = rng.uniform(-1, 1, env.action_space.shape)
                t0 = time.perf_counter()
                res = guarded(lambda: env.step(a))
                dt = time.perf_counter() - t0
                if res is None:
                    break
                obs, reward, term, trunc, info = res
                out["runaway_steps"] += 1
                out["nonfinite"] += int(not (np.all(np.isfinite(obs)) and np.isfinite(reward)))
                if info["diverged"]:
                    out["runaway_flagged"] += 1
                    out["runaway_worst_step_s"] = max(out["runaway_worst_step_s"], dt)
                if term or trunc:
                    break
            out["runaway_episodes"] += 1
        env.close()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    return out


def _collect(venv_step, reset, actions) -> np.ndarray:
    obs = [reset()]
    for a in actions:
        obs.append(venv_step(a))
    return np.array(obs)


def determinism(env_id: str, steps: int = 100, num_envs: int = 4, seed: int = 123, **kwargs: Any) -> dict:
    """The same seeds and actions through Sync, Async (spawn), the batched env and SB3's
    SubprocVecEnv (spawn, forkserver): largest observation difference to the SyncVectorEnv run,
    over the steps before any member's episode ends (autoreset conventions differ after)."""
    from stable_baselines3.common.vec_env import SubprocVecEnv

    rng = np.random.default_rng(seed)
    probe = gym.make(env_id, **kwargs)
    actions = rng.uniform(-1, 1, (steps, num_envs) + probe.action_space.shape)
    name = env_id if env_id.startswith("mbs_envs:") else "mbs_envs:" + env_id

    def make():
        return gym.make(name, **kwargs)

    runs: dict[str, np.ndarray] = {}
    dones: list[np.ndarray] = []

    def gym_run(venv):
        obs = [venv.reset(seed=seed)[0]]
        for a in actions:
            o, _, te, tr, _ = venv.step(a)
            obs.append(o)
            dones.append(te | tr)
        venv.close()
        return np.array(obs)

    runs["sync"] = gym_run(gym.vector.SyncVectorEnv([make] * num_envs))
    runs["async (spawn)"] = gym_run(gym.vector.AsyncVectorEnv([make] * num_envs, context="spawn"))
    runs["batched"] = gym_run(
        gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    )
    for method in ("spawn", "forkserver"):
        venv = SubprocVecEnv([make] * num_envs, start_method=method)
        venv.seed(seed)
        obs = [venv.reset()]
        for a in actions:
            obs.append(venv.step(a)[0])
        venv.close()
        runs[f"SB3 SubprocVecEnv ({method})"] = np.array(obs)
    first_done = min([k for k, d in enumerate(dones[:steps]) if np.any(d)] + [steps])
    upto = first_done + 1  # observations up to and including the first episode end
    ref = runs["sync"][:upto]
    return {"env_id": env_id, "steps_compared": int(upto - 1), "members": num_envs,
            "max_difference": {k: float(np.max(np.abs(v[:upto] - ref))) for k, v in runs.items()}}  # fmt: skip


#: the values each scene's edge parameters (registry) are driven to
EDGE_VALUES = (0.0, -1.0, math.nan, math.inf, 1e-6, 1e6)


def parameter_edges() -> list[dict]:
    """Every model x mass/length parameter x :data:`EDGE_VALUES`: ``ValueError`` (with its
    message) or, when accepted, a 1 s simulation's outcome (finite, divergence reported, energy drift)."""
    cases, seen = [], set()
    for s in SCENES:  # scenes sharing a model (Planar2R, Acrobot, Pendubot) share its cases: each once
        for name, extra in s.edge_parameters:
            key = (s.model, name, tuple(sorted(extra.items())))
            if key not in seen:
                seen.add(key)
                cases.append((load(s.model), name, extra))
    rows = []
    for cls, name, extra in cases:
        for value in EDGE_VALUES:
            row = {"model": cls.__name__, "parameter": name, "value": value}
            try:
                model = cls(**extra, **{name: value})
            except ValueError as e:
                rows.append({**row, "outcome": "ValueError", "message": str(e)})
                continue
            try:
                q0, v0 = model.moving_state()
            except ValueError as e:
                rows.append({**row, "outcome": "ValueError at assembly", "message": str(e)})
                continue
            tr = simulate(model, q0, v0, 1.0, dt=1e-3, integrator="rk4")  # constrained models: projection
            E = model.energy(tr.q, tr.v)
            finite = bool(np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)))
            scale = max(float(np.max(np.abs(E))), 1e-300)
            rows.append({**row, "outcome": "diverged (reported)" if np.any(tr.diverged) else "stable",
                         "all_finite": finite, "relative_energy_drift": float(np.max(np.abs(E - E[0]))) / scale})  # fmt: skip
    return rows


#: the calls :func:`adversarial_soak` makes that must be refused with ``ValueError`` and change nothing
REFUSED_CALLS = ("reset options q", "reset options type", "reset seed", "reset seed list", "reset mask", "action", "set_attr value",
                 "set_attr name", "model")  # fmt: skip
#: values a user may pass by mistake (``set_attr`` of every setting is tried with each)
BAD_VALUES = (float("nan"), float("inf"), -1.0, "0.01", None, True, 1j, [float("nan")] * 9, {"a": 1}, -(10**30))


def adversarial_soak(env_id: str, rounds: int = 500, num_envs: int = 4, seed: int = 0, **kwargs: Any) -> dict:
    """Random sequences of calls that change state, copy, refuse, seed, autoreset and set, on the batched env beside a twin.

    Each round is one of: a step (random actions; NaN for members being reset, whose action is ignored),
    a seeded reset, a deepcopy or pickle round trip of the env mid-episode, a valid ``set_attr`` of
    ``dt`` (given to both), or a refused call (:data:`REFUSED_CALLS`: bad options, seeds, masks, actions,
    ``set_attr`` of every setting with :data:`BAD_VALUES` and of names that are not settings, a model
    swap). The twin gets only the calls that must act, so after every round the two must agree bit for
    bit, and a refused call must leave the state, the generators and every setting as they were.

    Returns
    -------
    dict
        ``env_id``, ``rounds``, counts per kind of call (``counts``), ``refused`` calls in all,
        ``accepted_bad`` (a refused call that was accepted), ``changed_by_refusal``, ``disagreements``
        with the twin, ``other_exceptions`` (not ``ValueError``) and their first messages (``errors``).
    """
    import collections
    import copy
    import pickle

    rng = np.random.default_rng(seed)
    kwargs = {"max_episode_steps": 8, **kwargs}

    def make():
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs).unwrapped

    env, twin = make(), make()
    env.reset(seed=seed)
    twin.reset(seed=seed)
    nu, nq = env.model.nu, env.model.nq
    names = env.env.settings()
    counts: collections.Counter = collections.Counter()
    out = {"accepted_bad": 0, "changed_by_refusal": 0, "disagreements": 0, "other_exceptions": 0, "errors": []}

    def state(e):
        return (e._qc.copy(), e._vc.copy(), e._t.copy(), repr([g.bit_generator.state for g in e._rngs]),
                repr({k: getattr(e.env, k) for k in names}))  # fmt: skip

    def same(a, b):
        return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))

    for _ in range(rounds):
        kind = rng.choice(["step", "step", "step", "reset", "copy", "set dt", "refused", "refused"])
        counts[kind] += 1
        try:
            if kind == "step":
                a = rng.uniform(-2, 2, (num_envs, nu))
                mine = a.copy()
                mine[env._autoreset] = np.nan
                o1, r1 = env.step(mine)[:2]
                o2, r2 = twin.step(a)[:2]
                if not (np.array_equal(o1, o2) and np.array_equal(r1, r2)):
                    out["disagreements"] += 1
            elif kind == "reset":
                s = int(rng.integers(0, 2**31))
                if not np.array_equal(env.reset(seed=s)[0], twin.reset(seed=s)[0]):
                    out["disagreements"] += 1
            elif kind == "copy":
                env = copy.deepcopy(env) if rng.random() < 0.5 else pickle.loads(pickle.dumps(env))
            elif kind == "set dt":
                dt = float(rng.choice([0.005, 0.01, 0.02]))
                env.set_attr("dt", dt)
                twin.set_attr("dt", dt)
            else:
                call = str(rng.choice(REFUSED_CALLS))
                counts["refused: " + call] += 1
                name, value = str(rng.choice(names)), BAD_VALUES[int(rng.integers(len(BAD_VALUES)))]
                calls = {
                    "reset options q": lambda: env.reset(options={"q": np.full(nq, 1e9)}),
                    "reset options type": lambda: env.reset(options={"q": ["1"] * nq}),
                    "reset seed": lambda: env.reset(seed=value if value is not None else -1),
                    "reset seed list": lambda: env.reset(seed=[0] * (num_envs - 1) + [-1]),
                    "reset mask": lambda: env.reset(
                        options={"reset_mask": [value] * num_envs if value is not True else "yes"}
                    ),
                    "action": lambda: env.step(
                        np.where(env._autoreset[:, None], 0.0, np.nan) * np.ones((num_envs, nu))
                        if not env._autoreset.all()
                        else "x"
                    ),  # fmt: skip
                    "set_attr value": lambda: env.set_attr(name, value),
                    "set_attr name": lambda: env.set_attr(
                        str(rng.choice(["model", "max_episode_steps", "n_links", "dtt", "np_random"])), 1
                    ),
                    "model": lambda: setattr(env, "model", None),
                }
                before = state(env)
                try:
                    calls[call]()
                except ValueError:
                    if not same(state(env), before):
                        out["changed_by_refusal"] += 1
                else:
                    if (
                        call == "set_attr value"
                    ):  # a value valid for that setting (e.g. 1j is not, -1.0 may be): restore
                        setattr(env.env, name, getattr(twin.env, name))
                    else:
                        out["accepted_bad"] += 1
        except Exception as e:  # anything but a ValueError from a refused call is a defect
            out["other_exceptions"] += 1
            if len(out["errors"]) < 5:
                out["errors"].append(f"{kind}: {type(e).__name__}: {str(e)[:160]}")
        if not np.array_equal(env._qc, twin._qc):
            out["disagreements"] += 1
            env, twin = make(), make()  # start over: one divergence would count every later round
            env.reset(seed=seed)
            twin.reset(seed=seed)
    out.update(
        env_id=env_id,
        rounds=rounds,
        counts=dict(counts),
        refused=sum(v for k, v in counts.items() if k.startswith("refused:")),
    )
    return out


#: the program :func:`threads_cold` runs in a fresh interpreter: one env per thread, made, reset and stepped
_THREADS_PROGRAM = """
import concurrent.futures as cf, json, sys
import numpy as np, gymnasium as gym, mbs_envs

def job(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    for _ in range(steps):
        obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    env.close()
    if not np.all(np.isfinite(obs)):
        raise ValueError("non-finite observation")

ids, per_id, steps = json.loads(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
errors = []
with cf.ThreadPoolExecutor(len(ids) * per_id) as ex:
    futures = [(i, ex.submit(job, i)) for i in ids for _ in range(per_id)]
    for i, f in futures:
        try:
            f.result()
        except Exception as e:
            errors.append(f"{i}: {type(e).__name__}: {e}")
print(json.dumps({"jobs": len(futures), "errors": errors}))
"""


def threads_cold(ids: list[str], per_id: int = 4, runs: int = 1, steps: int = 3) -> dict:
    """Envs built in threads on a cold cache: ``runs`` fresh interpreters, each with empty numba and derivation caches
    (the first use after an install), run ``per_id`` threads per id at once, each making, resetting and stepping its
    own env. Returns the jobs, the failed ones and their first errors."""
    import json
    import os
    import subprocess
    import sys
    import tempfile

    jobs, errors = 0, []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "numba"),
                   "MBS_ENVS_DERIVED_CACHE": os.path.join(tmp, "derived")}  # fmt: skip
            env.pop("MBS_ENVS_JIT", None)  # the default: compiled in the background, the kernels' Python meanwhile
            res = subprocess.run([sys.executable, "-c", _THREADS_PROGRAM, json.dumps(ids), str(per_id), str(steps)],
                                 cwd=tmp, env=env, capture_output=True, text=True, timeout=1800)  # fmt: skip
            if res.returncode:
                jobs += len(ids) * per_id
                errors.append(res.stderr.strip().splitlines()[-1] if res.stderr.strip() else f"exit {res.returncode}")
                continue
            out = json.loads(res.stdout.strip().splitlines()[-1])
            jobs += out["jobs"]
            errors += out["errors"]
    return {"ids": list(ids), "per_id": per_id, "runs": runs, "jobs": jobs, "failed": len(errors), "errors": errors[:5]}
