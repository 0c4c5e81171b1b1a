"""The six-axis robustness sweep on every scene, with ranges that suit each.

The axes are the DFKI benchmark's robustness v2 (:mod:`mbs_envs.studies.dfki`), carried over to our
scenes at their defaults (the compared ids: Planar2R, FourBar, SerialChain, RollingDisk, Acrobot-v1,
Pendubot-v1). Every axis is one batched rollout (:func:`mbs_envs.studies.robustness.run`) of
``values x seeds`` members, each member one value of the axis and one test seed (the same seeds for
every value: the value is the only difference between the columns):

- **model**: each parameter of :attr:`SceneSweep.factors` times ``[1 - spread, 1 + spread]``
  (``spread`` 0.25, theirs), one at a time (arrays, the chain's per-link values, scaled whole), and the
  viscous joint friction of :attr:`SceneSweep.damping` from 0 to ``DAMPING_RATE`` times the torque scale of its
  coordinate (0.02 s/rad: their top, 0.1 N m s/rad, is 0.017 of their 6 N m). Controllers keep the nominal model,
  actuators their nominal limits (as the comparison's mismatch). A variation the model refuses (none at these
  spreads) is skipped and counted;
- **velocity noise**: Gaussian noise of std 0 to 0.5 (their range, in the observation's units: rad/s,
  m/s) on every observation entry that depends on the velocities (found by :func:`velocity_entries`);
- **torque noise**: std 0 to 0.18 of each input's limit (their 1.1 N m of 6 N m);
- **torque response**: a first-order actuator with responsiveness 0.1 to 2 (theirs);
- **time delay**: the controller sees the observation 0 to 0.05 s old (theirs: 0-0.04 s at 2 ms; ours
  whole control steps of 10 ms, so 0-5 steps);
- **perturbations**: their random Gaussian torque pulses (:func:`mbs_envs.studies.robustness.random_pulses`)
  on the coordinates :attr:`SceneSweep.pulse_coordinates`, heights ``U(1/12, 5/6)`` of the coordinate's torque
  scale (their 0.5-5 N m of 6 N m), widths 0.05-0.1 s, as impulses (the constraints' own impulse included
  on FourBar and RollingDisk).

A coordinate's torque scale is the limit of the input that drives it, or the scene's largest limit for an
undriven one (the acrobot's shoulder, the disk's lean). Success is the scene's own rule: on the swing-up
scenes the comparison's (both angles within 0.1 rad of upright for the last 2 s); on the tracking scenes the
episode runs to its end with a settled RMS tracking error (after the first second; the disk: its heading
error) of at most :data:`TOLERANCE`. The score of a policy on a scene is the mean of the six success fractions.
"""

from __future__ import annotations

import dataclasses
from types import MappingProxyType
from typing import Any, Callable, Mapping

import gymnasium as gym
import numpy as np

from ..envs import registry
from .robustness import Perturbation, random_pulses, run

#: the axes, in the DFKI order
AXES = ("model", "velocity noise", "torque noise", "torque response", "time delay", "perturbations")
#: [rad] a tracking episode succeeds with a settled RMS error up to this (the swing-up's tolerance)
TOLERANCE = 0.1
#: [s/rad] top of the damping axis per unit of the coordinate's torque scale
DAMPING_RATE = 0.02
#: values per axis and test seeds per value of :func:`sweep` by default, and the perturbation episodes
N_VALUES, N_SEEDS, PULSE_EPISODES = 11, 3, 30


@dataclasses.dataclass(frozen=True)
class SceneSweep:
    """What one scene's sweep varies (module docstring for the shared ranges).

    Attributes
    ----------
    factors : tuple of str
        Model parameters scaled by ``[1 - spread, 1 + spread]``.
    damping : Mapping[str, tuple of int]
        Friction parameter -> the velocity coordinates it damps (its top: ``DAMPING_RATE`` times their
        largest torque scale).
    pulse_coordinates : tuple of int
        Velocity coordinates the pulses push.
    pulses_per_coordinate : int
    pulse_gap : float
        Least spacing of the pulse centres [s].
    spread : float
    velocity_noise : (float, float)
        Noise std range [rad/s, m/s].
    torque_noise : (float, float)
        Std range, fractions of each input's limit.
    response : (float, float)
    delay : (float, float)
        [s].
    pulse_width : (float, float)
        [s].
    pulse_height : (float, float)
        Fractions of the coordinate's torque scale.
    """

    factors: tuple[str, ...]
    damping: Mapping[str, tuple[int, ...]]
    pulse_coordinates: tuple[int, ...]
    pulses_per_coordinate: int = 3
    pulse_gap: float = 1.0
    spread: float = 0.25
    velocity_noise: tuple[float, float] = (0.0, 0.5)
    torque_noise: tuple[float, float] = (0.0, 0.18)
    response: tuple[float, float] = (0.1, 2.0)
    delay: tuple[float, float] = (0.0, 0.05)
    pulse_width: tuple[float, float] = (0.05, 0.1)
    pulse_height: tuple[float, float] = (1 / 12, 5 / 6)


_TWO_LINKS = ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2")
_TWO_JOINTS = MappingProxyType({"b1": (0,), "b2": (1,)})

#: the sweep of each compared scene. FourBar keeps its lengths (they are the loop the reference lives on);
#: the chains (5 s episodes, ten joints) get one pulse per joint, 0.4 s apart at least; the disk's radius also moves
#: its critical spin, against which each episode's commanded spin is drawn (the task changes with the plant, as
#: under the comparison's mismatch); the cart-pole's pulses push the cart (a pulse of the undriven pole's torque
#: scale, the cart's 10 N taken as N m, would throw its 0.03 kg m^2 about at tens of rad/s)
SWEEPS: Mapping[str, SceneSweep] = MappingProxyType({
    "Planar2R": SceneSweep(_TWO_LINKS, _TWO_JOINTS, (0, 1), pulse_gap=0.5),
    "FourBar": SceneSweep(("m1", "m2", "m3", "r1", "r2", "r3", "I1", "I2", "I3"),
                          MappingProxyType({"b1": (0,), "b2": (1,), "b3": (2,)}), (0,)),
    "SerialChain": SceneSweep(("m", "l", "r", "I"), MappingProxyType({"b": tuple(range(10))}), tuple(range(10)),
                              pulses_per_coordinate=1, pulse_gap=0.4),
    "SpatialChain": SceneSweep(("m", "l", "com", "inertia"), MappingProxyType({"b": tuple(range(10))}), tuple(range(10)),
                               pulses_per_coordinate=1, pulse_gap=0.4),
    "RollingDisk": SceneSweep(("m", "r"), MappingProxyType({"b_pivot": (3,), "b_roll": (5,)}), (3, 4, 5), pulses_per_coordinate=2),
    "SliderCrank": SceneSweep(("m1", "m2", "m3"), MappingProxyType({"b_th": (0,), "b_s": (2,)}), (0,)),
    "CartDoublePendulum": SceneSweep(("m0", "m1", "m2", "l1", "l2"), MappingProxyType({"b_x": (0,), "b_1": (1,), "b_2": (2,)}), (0, 1, 2),
                                     pulses_per_coordinate=2, pulse_gap=0.5),
    "CartPoleSwingUp": SceneSweep(("m0", "m", "l"), MappingProxyType({"b_x": (0,), "b_th": (1,)}), (0,)),
    "Acrobot": SceneSweep(_TWO_LINKS, _TWO_JOINTS, (0, 1)),
    "Pendubot": SceneSweep(_TWO_LINKS, _TWO_JOINTS, (0, 1)),
})  # fmt: skip


def torque_scale(model: Any, u_max: np.ndarray) -> np.ndarray:
    """Per velocity coordinate, the limit of the input that drives it (``max_j |B_ij| u_max_j``), or the
    largest limit where no input does, shape ``(nv,)`` [N m or N]."""
    B = np.abs(np.asarray(model.actuation, float))
    driven = (B * np.asarray(u_max, float)).max(axis=1)
    return np.where(driven > 0, driven, float(np.max(u_max)))


def velocity_entries(env: Any, seed: int = 0) -> tuple[int, ...]:
    """The observation entries that depend on the velocities: those that change when only ``v`` does
    (observed at one start state with ``v`` and with ``v`` + 1)."""
    base = env.unwrapped
    base.reset(seed=seed)
    q, v, now, task = base.q, base.v, base.now(), base._task
    a = np.asarray(base.observe(q, v, now, task), float)
    b = np.asarray(base.observe(q, v + 1.0, now, task), float)
    return tuple(int(i) for i in np.flatnonzero(a != b))


def model_variations(
    scene: str, params: Any, u_max: np.ndarray, model: Any, n: int
) -> list[tuple[str, float, dict[str, Any] | None]]:
    """The model axis as ``(parameter, value, params changes or None)``.

    ``value``: the factor of a scaled parameter, the friction in N m s/rad of a damping one (the top, for an
    array); None where the parameters are refused (not simulated, counted as skipped)."""
    spec = SWEEPS[scene]
    out: list[tuple[str, float, dict[str, Any] | None]] = []
    for name in spec.factors:
        for f in np.linspace(1 - spec.spread, 1 + spec.spread, n):
            out.append((name, float(f), _checked(params, {name: np.asarray(getattr(params, name)) * f})))
    scale = torque_scale(model, u_max)
    for name, coords in spec.damping.items():
        top = DAMPING_RATE * scale[list(coords)]
        for s in np.linspace(0.0, 1.0, (n + 1) // 2):
            value = top * s if np.ndim(getattr(params, name)) else float(top.max() * s)
            out.append((name, float(np.max(value)), _checked(params, {name: value})))
    return out


def _checked(params: Any, changes: dict[str, Any]) -> dict[str, Any] | None:
    plain = {k: (np.asarray(v).tolist() if np.ndim(v) else float(v)) for k, v in changes.items()}
    try:
        params.replace(**plain)
    except ValueError:
        return None
    return plain


def success(scene: str, episodes: list[Any], tolerance: float = TOLERANCE) -> np.ndarray:
    """The scene's success rule (module docstring) on recorded episodes, bool ``(n,)``."""
    from .evaluation import episode_metrics, swing_up_metrics

    if registry.scene(scene).scoring == "swing-up":
        return np.array([swing_up_metrics(e)["success"] for e in episodes], bool)
    return np.array([not e.terminated and episode_metrics(e)["rms_error_settled"] <= tolerance for e in episodes], bool)


def sweep(scene: str, make_policy: Callable[[Any], Any], n: int = N_VALUES, seeds: tuple[int, ...] = tuple(range(N_SEEDS)),
          pulse_episodes: int = PULSE_EPISODES, seed: int = 0, axes: tuple[str, ...] = AXES) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The six-axis sweep of one policy on one scene.

    Parameters
    ----------
    scene : str
        A key of :data:`SWEEPS`.
    make_policy : callable
        ``make_policy(nominal_env) -> policy`` (called once per batch; its memory lives in ``state``).
    n : int
        Values per axis (the damping axes ``(n + 1) // 2``).
    seeds : tuple of int
        Test seeds (starts and references) of every value.
    pulse_episodes : int
        Members of the perturbation axis, each its own random pulses and the seed ``seeds[i % len(seeds)]``.
    seed : int
        Seeds the noise and the pulses.

    Returns
    -------
    dict
        Per axis: ``values`` (one per member: the model axis ``(parameter, value)``), ``seeds``, ``success``
        (bool per member), ``fraction``, and for the model axis ``skipped``; ``"score"``: the mean of the fractions.
    """
    from .comparison import SCENES, model_kwargs

    spec = SWEEPS[scene]
    env_id, kwargs, _ = SCENES[scene]
    nominal = gym.make(env_id, **kwargs)
    base = nominal.unwrapped
    u_max = np.asarray(base.u_max, float)
    dt, steps = float(base.dt), nominal.spec.max_episode_steps
    rng = np.random.default_rng(seed)
    seeds = [int(s) for s in seeds]
    out: dict[str, dict[str, Any]] = {}

    def batch(members: list[int], p: Perturbation, **env_kwargs: Any) -> np.ndarray:
        venv = gym.make_vec(env_id, num_envs=len(members), vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                            **{**kwargs, **env_kwargs})  # fmt: skip
        res = run(venv, make_policy(nominal), members, p, noise_seed=int(rng.integers(2**31)), record=True)
        venv.close()
        return success(scene, res["episodes"])

    def tiled(values: np.ndarray) -> np.ndarray:
        return np.repeat(values, len(seeds), axis=0)

    for axis in axes:
        if axis == "model":
            points = model_variations(scene, base.model.params, u_max, base.model, n)
            kept = [(name, value, changes) for name, value, changes in points if changes is not None]
            members = seeds * len(kept)
            if getattr(base.model, "batched_params", False):
                ok = batch(members, Perturbation(), member_params=[c for _, _, c in kept for _ in seeds])
            else:  # one batch per variation (the model's parameters are not per member)
                ok = np.concatenate([batch(seeds, Perturbation(), **model_kwargs(scene, c)) for _, _, c in kept])
            out[axis] = {"values": [(name, value) for name, value, _ in kept for _ in seeds], "seeds": members, "success": ok,
                         "skipped": [(name, value) for name, value, c in points if c is None]}  # fmt: skip
        elif axis == "perturbations":
            coords = list(spec.pulse_coordinates)
            height = np.outer(spec.pulse_height, torque_scale(base.model, u_max)[coords])
            pushed = random_pulses(rng, pulse_episodes, np.arange(steps) * dt, len(coords), spec.pulses_per_coordinate,
                                   spec.pulse_gap, spec.pulse_width, (height[0], height[1]))  # fmt: skip
            pulses = np.zeros((pulse_episodes, steps, base.model.nv))
            pulses[..., coords] = pushed
            members = [seeds[i % len(seeds)] for i in range(pulse_episodes)]
            out[axis] = {
                "values": list(range(pulse_episodes)),
                "seeds": members,
                "success": batch(members, Perturbation(pulses=pulses)),
            }
        else:
            values = np.linspace(*getattr(spec, {"velocity noise": "velocity_noise", "torque noise": "torque_noise",
                                                 "torque response": "response", "time delay": "delay"}[axis]), n)  # fmt: skip
            if axis == "velocity noise":
                p = Perturbation(noise_sigma=tiled(values), noise_index=velocity_entries(nominal))
            elif axis == "torque noise":
                p = Perturbation(torque_sigma=tiled(values[:, None] * u_max))
            elif axis == "torque response":
                p = Perturbation(response=tiled(values))
            else:
                values = np.rint(values / dt) * dt
                p = Perturbation(delay=tiled(np.rint(values / dt).astype(int)))
            members = seeds * n
            out[axis] = {"values": tiled(values).tolist(), "seeds": members, "success": batch(members, p)}
        out[axis]["fraction"] = float(np.mean(out[axis]["success"]))
    out["score"] = {"value": float(np.mean([out[a]["fraction"] for a in axes]))}
    return out


def sweep_job(task: Mapping[str, Any]) -> dict[str, Any]:
    """One policy on one scene (a picklable task for :func:`mbs_envs.studies.parallel.run_tasks`).

    ``task``: ``scene``, ``spec`` (a controller ``"module:Class"``, an agent folder, or an RL + LQR pair, as
    :func:`mbs_envs.studies.comparison.load_policy` reads them), and :func:`sweep`'s ``n``, ``seeds``,
    ``pulse_episodes``, ``seed``. Returns the sweep and its wall time [s].
    """
    import time

    import torch

    from .comparison import load_policy

    torch.set_num_threads(1)
    tic = time.perf_counter()
    res = sweep(task["scene"], lambda env: load_policy(task["spec"], env), n=task.get("n", N_VALUES),
                seeds=tuple(task.get("seeds", range(N_SEEDS))), pulse_episodes=task.get("pulse_episodes", PULSE_EPISODES),
                seed=task.get("seed", 0))  # fmt: skip
    return {"sweep": res, "wall_s": time.perf_counter() - tic}


def policies(scene: str, agents: Mapping[str, list[str]]) -> dict[str, list[str]]:
    """Every policy of a scene as the comparison runs them: the model-based controllers, then the shipped agents
    ``agents`` (:func:`mbs_envs.studies.comparison.find_agents`: every training seed and, on the swing-up scenes,
    the RL + LQR pairs); name -> specs."""
    from .comparison import SCENES

    return {**{name: [spec] for name, spec in SCENES[scene][2].items()}, **agents}


def summarize(sweeps: list[dict[str, Any]], axes: tuple[str, ...] = AXES) -> dict[str, Any]:
    """A policy's sweeps (one per training seed) pooled: per axis the success fraction over every member of every
    training seed, the score (mean of the fractions), and each training seed's score."""
    fractions = {a: float(np.mean(np.concatenate([np.asarray(r[a]["success"], float) for r in sweeps]))) for a in axes}
    return {"fractions": fractions, "score": float(np.mean(list(fractions.values()))),
            "seed_scores": [float(r["score"]["value"]) for r in sweeps]}  # fmt: skip


def tasks(policies_by_scene: Mapping[str, Mapping[str, list[str]]], n: int = N_VALUES, n_seeds: int = N_SEEDS,
          pulse_episodes: int = PULSE_EPISODES, seed: int = 0) -> list[dict[str, Any]]:  # fmt: skip
    """One :func:`sweep_job` task per scene, policy and training seed (``policies_by_scene``: scene -> name -> specs),
    on the first ``n_seeds`` test seeds."""
    from .seeds import test_seeds

    return [{"scene": scene, "policy": name, "train_seed": k, "spec": spec, "n": n, "seeds": test_seeds(n_seeds),
             "pulse_episodes": pulse_episodes, "seed": seed}
            for scene, by_name in policies_by_scene.items() for name, specs in by_name.items() for k, spec in enumerate(specs)]  # fmt: skip


def collect(jobs: list[Mapping[str, Any]], results: list[Mapping[str, Any]]) -> tuple[list[dict[str, Any]], dict, dict]:
    """The sweeps of :func:`tasks` as rows (one per member: scene, policy, kind, training seed, axis, parameter,
    value, seed, success), a summary (scene -> policy -> :func:`summarize`, its kind, wall times, and the model
    variations skipped), and the sweeps themselves (scene -> policy -> one per training seed, for :func:`plot`)."""
    from .comparison import kind_of

    rows: list[dict[str, Any]] = []
    grouped: dict[str, dict[str, list]] = {}
    for job, res in zip(jobs, results):
        grouped.setdefault(job["scene"], {}).setdefault(job["policy"], []).append(res)
        for axis in AXES:
            r = res["sweep"][axis]
            for value, s, ok in zip(r["values"], r["seeds"], r["success"]):
                parameter, value = value if axis == "model" else (axis, value)
                rows.append({"scene": job["scene"], "policy": job["policy"], "kind": kind_of(job["policy"]), "train_seed": job["train_seed"],
                             "axis": axis, "parameter": parameter, "value": value, "seed": s, "success": bool(ok)})  # fmt: skip
    summary = {scene: {name: {**summarize([r["sweep"] for r in rs]), "kind": kind_of(name), "wall_s": [r["wall_s"] for r in rs],
                              "skipped": rs[0]["sweep"]["model"]["skipped"]}
                       for name, rs in by_name.items()} for scene, by_name in grouped.items()}  # fmt: skip
    sweeps = {
        scene: {name: [r["sweep"] for r in rs] for name, rs in by_name.items()} for scene, by_name in grouped.items()
    }
    return rows, summary, sweeps


def plot(sweeps: Mapping[str, Mapping[str, list]], folder: Any) -> None:
    """``robustness_<scene>.png`` in ``folder`` for each scene of :func:`collect`'s sweeps."""
    import pathlib

    from .robustness import plot_success

    for scene, by_policy in sweeps.items():
        plot_success(
            dict(by_policy),
            AXES,
            f"{scene}: robustness sweep, success",
            pathlib.Path(folder) / f"robustness_{scene}.png",
        )


def markdown_table(by_policy: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Markdown rows of one scene's policies (:func:`collect`'s summary): success [%] per axis, the score, and the
    median wall time of one sweep."""
    out = ["| policy | side | " + " | ".join(AXES) + " | score | wall [s] |", "|---" * (len(AXES) + 4) + "|"]
    for name, s in by_policy.items():
        out.append(f"| {name} | {s['kind']} | " + " | ".join(f"{100 * s['fractions'][a]:.0f}" for a in AXES)
                   + f" | **{s['score']:.3f}** | {np.median(s['wall_s']):.0f} |")  # fmt: skip
    return out


def describe(n: int, n_seeds: int, pulse_episodes: int) -> str:
    """One paragraph that says what the sweep's tables show."""
    return (
        f"Six axes (`mbs_envs/studies/scene_robustness.py` gives each scene's ranges), {n} values per axis, {n_seeds} test "
        f"seed(s) per value, {pulse_episodes} perturbation episodes: model parameters x [0.75, 1.25] one at a time and "
        "joint friction from 0, velocity-measurement noise (std 0-0.5), torque noise (std 0-0.18 of each limit), a "
        "first-order torque response (0.1-2), an observation delay (0-0.05 s), random torque pulses. Success [%] by the "
        f"scene's rule (tracking: the whole episode with a settled RMS error <= {TOLERANCE} rad; swing-up: within 0.1 rad "
        "of upright for the last 2 s), agents pooled over their training seeds; score = mean of the six (the DFKI "
        "benchmark's robustness v2 carried over to our scenes). Wall: median seconds of one sweep in one process."
    )
