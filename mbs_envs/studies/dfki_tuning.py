"""The energy-pumping controllers' gains tuned on the DFKI protocol itself, as the leaderboard's entries are tuned on
its plant (``scripts/dfki.py --tune``).

The swing-up scenes' gains (:mod:`mbs_envs.studies.tuning`) were picked for our 1 m, 10 / 5 N m arm; on the protocol's
0.3 / 0.2 m plant with 6 N m the acrobot's energy controllers never swung up with them. Here the same grids run on the
protocol id (``mbs_envs/AcrobotDFKI-v1``, ``mbs_envs/PendubotDFKI-v1``):

- **swing-up + LQR**: the first grid (:func:`protocol_grid`: swing-up + LQR's, :func:`~mbs_envs.studies.tuning.swing_up_grid`,
  widened upward in ``k_q, k_v, k_E``, where a first run's picks sat at its edges; 2,560 candidates), then the second around its pick (:func:`~mbs_envs.studies.tuning.swing_up_refine_grid`:
  the LQR's input weight with the catch level, 128);
- **adaptive swing-up + LQR**: the first grid with the LQR's input weight of swing-up + LQR's pick (its LQR is solved
  again per member as its identification moves, with one weight for the batch); then its identification's outlier
  gate (:func:`controllers.identification.explained`; :data:`GATES`, none among them) on the three plants and on 50
  episodes of the benchmark's random perturbation pulses on the protocol's plant (:func:`pulse_success`), drawn from
  :data:`PULSE_SEED`, not the robustness sweep's draws: a push's work biases the identification, and the gate, which
  leaves such windows out, also slows the identification of a plant far from the prior, so it is picked where both
  are scored;
- **identified iLQR + TVLQR**: its pumping serves the identification of its first seconds, not a swing-up, so the
  adaptive controller's pick is not necessarily right for it: two candidates, its entry tuned on our own scene of
  the task (``mbs_envs/<scene>-v1``) and the adaptive controller's pick on the protocol, one rollout each (the
  planner's LQR weights differ, and it solves them online).

Every candidate is one member of a single batched rollout per plant (the laws broadcast over members: the gains as
arrays of shape ``(n,)``, the LQR's gain and cost-to-go per member; :func:`with_member_gains`; the tests hold this
equal to one rollout per candidate). The plants: the protocol's, and its masses and lengths x 0.8 and x 1.2 (the
tuning's conditions, :data:`~mbs_envs.studies.tuning.TUNING_CONDITIONS`). A candidate ranks by its failures under
the protocol's success rule over the three (:func:`mbs_envs.studies.dfki.evaluate`), then by its mean simulation-v2
score over them (higher first). The protocol starts at rest, so one episode per plant is the whole of it.

**The catch tuned for robustness** (:func:`robust_catch`, ``scripts/dfki.py --tune-robust-catch``): the gains above
are ranked by the nominal score, and the benchmark also scores robustness, where a catching LQR's gains matter most
(smaller gains tolerate more delay). For every policy with a catching LQR (the energy controllers; every agent with
the LQR catching, its training seeds together) the LQR's input weight and catch level are picked for the robustness
score on a tuning set of the six axes -- their values drawn uniformly over the benchmark's ranges from another seed,
other noise and pulses (:data:`ROBUST_SET`) -- never on the benchmark's grid, which scores the pick. A second stage
(``--tune-robust-catch --release-stage``, :func:`release_grid`) keeps each group's pick and tries the factor
``release`` on its level beyond which the LQR hands back to the swing-up, by the same rule on the same tuning set.
"""

from __future__ import annotations

import time
from types import MappingProxyType
from typing import Any, Callable, Mapping

import gymnasium as gym
import numpy as np

from . import dfki
from .comparison import listed, scaled_params
from .tuning import TUNING_CONDITIONS, swing_up_grid, swing_up_refine_grid

#: the controllers tuned on the protocol: display name -> ``"module:Class"``
TUNED = {
    "swing-up + LQR": "mbs_envs.controllers:SwingUpLQR",
    "adaptive swing-up + LQR": "mbs_envs.controllers:AdaptiveSwingUpLQR",
    "identified iLQR + TVLQR": "mbs_envs.controllers:PlannedSwingUp",
}
#: the LQR's input weight [(N m)^-2] of the first stage's candidates (the scenes' first stage, :mod:`mbs_envs.studies.tuning`)
FIRST_STAGE_R = 1.0
#: the gains a member may carry (:func:`with_member_gains`)
MEMBER_GAINS = ("k_q", "k_v", "k_E", "catch")
#: the identification's outlier gates the adaptive controller's last stage compares (None: every window taken;
#: :func:`controllers.identification.explained`)
GATES = (None, 0.5, 0.25, 0.1, 0.05)
#: the last stage's pulse episodes: the benchmark's random perturbation pulses (:func:`mbs_envs.studies.dfki.random_pulses`)
#: drawn from this seed (the robustness sweep draws its own from its seed, 0 in the report)
PULSE_SEED = 1


def protocol_grid() -> list[dict[str, float]]:
    """The first stage's candidates on the protocol: swing-up + LQR's grid (:func:`~mbs_envs.studies.tuning.swing_up_grid`)
    with ``k_q`` up to 200 1/s^2, ``k_v`` up to 40 1/s and ``k_E`` up to 64 1/(J s) (a run on that grid picked its top
    ``k_E`` on both protocols and its top ``k_q`` and ``k_v`` on the pendubot's), the catch level as there."""
    return swing_up_grid(
        k_q=(1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0),
        k_v=(0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0),
        k_E=(0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0),
    )


def with_member_gains(controller: Any, entries: list[dict[str, Any]]) -> Any:
    """``controller`` (built with ``entries[0]``) carrying each entry's gains as member ``i`` of a batch.

    The pumping gains and the catch level become arrays of shape ``(n,)``; where the entries' ``lqr_r`` differ, the
    LQR's ``K`` ``(n, 1, 4)`` and ``S`` ``(n, 4, 4)`` are solved per member on the controller's model. Valid for
    :class:`controllers.swingup.SwingUpLQR` and, with one ``lqr_r`` for all, its adaptive subclass (whose LQR is
    solved per member from its identified model with the controller's one weight).

    Raises
    ------
    ValueError
        Where the entries' ``lqr_r`` differ on a controller that solves its LQR online.
    """
    from mbs_envs.controllers.adaptive_swingup import AdaptiveSwingUpLQR
    from mbs_envs.controllers.swingup import upright_lqr

    for key in MEMBER_GAINS:
        setattr(controller, key, np.array([float(e[key]) for e in entries]))
    if any(e.get("gate") is not None for e in entries):  # the identification's gate, inf where a member has none
        controller.gate = np.array([np.inf if e.get("gate") is None else float(e["gate"]) for e in entries])
    r = [float(e.get("lqr_r", controller.lqr_r)) for e in entries]
    if len(set(r)) > 1:
        if isinstance(controller, AdaptiveSwingUpLQR):
            raise ValueError(
                "with_member_gains: entries' lqr_r differ, but an adaptive controller solves its LQR with one weight"
            )
        gains = [upright_lqr(controller.model, controller.Q, np.full((1, 1), ri)) for ri in r]
        controller.K = np.stack([K for K, _ in gains])
        controller.S = np.stack([S for _, S in gains])
    return controller


def plant_kwargs(env_id: str, scale: float) -> dict[str, Any]:
    """``gym.make`` keywords of the protocol's plant with masses and lengths times ``scale`` (the preset's actuators)."""
    if scale == 1.0:
        return {}
    return {"params": listed(scaled_params(gym.make(env_id).unwrapped.model, scale))}


def scores(env_id: str, spec: str, entries: list[dict[str, Any]], max_episode_steps: int | None = None,
           batched: bool = True) -> dict[str, np.ndarray]:  # fmt: skip
    """Success and simulation-v2 score of every candidate under each tuning plant, one batched rollout per plant
    (``batched=False``: one rollout per candidate and plant).

    Returns
    -------
    dict
        Condition name -> array ``(len(entries), 2)`` of (success, score).
    """
    from .evaluation import make_controller

    if not batched:
        each = [scores(env_id, spec, [e], max_episode_steps) for e in entries]
        return {c: np.concatenate([r[c] for r in each]) for c in each[0]}
    env = gym.make(env_id)
    p = env.unwrapped.model.params
    out = {}
    extra = {} if max_episode_steps is None else {"max_episode_steps": max_episode_steps}
    policy = make_controller(spec, env, entries[0])  # its memory is in SB3's state: one object serves every plant
    if len(entries) > 1:
        policy = with_member_gains(policy, entries)
    for cond in TUNING_CONDITIONS:
        venv = gym.make_vec(env_id, num_envs=len(entries), vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                            **plant_kwargs(env_id, cond.scale), **extra)  # fmt: skip
        runs = dfki.record(venv, policy, list(range(len(entries))))
        venv.close()
        out[cond.name] = np.array([(c["success"], c["score"]) for c in dfki.evaluate(runs, p.l1, p.l2)])
    return out


def pulse_success(env_id: str, spec: str, entries: list[dict[str, Any]], episodes: int = dfki.PULSES["episodes"],
                  seed: int = PULSE_SEED) -> np.ndarray:  # fmt: skip
    """The fraction of ``episodes`` pulse episodes (the benchmark's random pulses drawn from ``seed``, the same for every
    candidate) each candidate ends upright in, by the robustness sweep's final-state rule: one batched rollout of
    ``len(entries) * episodes`` members. Returns shape ``(len(entries),)``."""
    from .evaluation import make_controller
    from .robustness import Perturbation, run

    env = gym.make(env_id)
    steps, dt = env.spec.max_episode_steps, float(env.unwrapped.dt)
    pulses = dfki.random_pulses(np.random.default_rng(seed), episodes, np.arange(steps) * dt)
    members = [e for e in entries for _ in range(episodes)]
    policy = with_member_gains(make_controller(spec, env, entries[0]), members)
    venv = gym.make_vec(
        env_id, num_envs=len(members), vectorization_mode="vector_entry_point", autoreset_mode="Disabled"
    )
    res = run(
        venv,
        policy,
        list(range(len(members))),
        Perturbation(pulses=np.tile(pulses, (len(entries), 1, 1))),
        noise_seed=seed,
    )
    venv.close()
    return dfki.run_success(res).reshape(len(entries), episodes).mean(axis=1)


def rank(per_condition: dict[str, np.ndarray], episodes: Mapping[str, int] | None = None) -> np.ndarray:
    """Candidate indices best first: fewest failed episodes over the conditions (``episodes``: a condition's episodes per
    candidate, 1 where not given; its success column a fraction), then the highest mean score over the conditions that
    have one (NaN: none)."""
    episodes = episodes or {}
    failures = sum(np.rint((1.0 - v[:, 0]) * episodes.get(c, 1)) for c, v in per_condition.items())
    scored = np.stack([v[:, 1] for v in per_condition.values() if not np.isnan(v[:, 1]).all()])
    return np.lexsort((-scored.mean(axis=0), failures))


def stage(env_id: str, spec: str, entries: list[dict[str, Any]], pulses: int = 0,
          **kwargs: Any) -> tuple[dict[str, Any], list[dict[str, Any]]]:  # fmt: skip
    """Score ``entries`` (:func:`scores`; with ``pulses`` > 0 also :func:`pulse_success` on that many episodes, their
    failures counted as the plants' are) and return the best entry and one row per candidate."""
    per = scores(env_id, spec, entries, **kwargs)
    episodes = {}
    if pulses:
        per["pulses"] = np.stack([pulse_success(env_id, spec, entries, pulses), np.full(len(entries), np.nan)], axis=1)
        episodes["pulses"] = pulses
    rows = [{"entry": e, **{f"{c} success": float(v[i, 0]) for c, v in per.items()},
             **{f"{c} score": float(v[i, 1]) for c, v in per.items() if not np.isnan(v[i, 1])}} for i, e in enumerate(entries)]  # fmt: skip
    return entries[int(rank(per, episodes)[0])], rows


def tune(env_id: str, start: dict[str, Any] | None = None, grid: Callable[[], list[dict[str, Any]]] = protocol_grid,
         planner_own: dict[str, Any] | None = None, gates: tuple = GATES, pulse_episodes: int = dfki.PULSES["episodes"], **kwargs: Any) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The controllers of :data:`TUNED` on the protocol id ``env_id`` (module docstring).

    Parameters
    ----------
    start : dict, optional
        Skip swing-up + LQR's first stage and refine from this entry.
    grid : callable
        The first stage's candidates (default :func:`protocol_grid`; the tests pass a small one).
    planner_own : dict, optional
        The planner's entry tuned on our own scene of the task (its first candidate); default
        :func:`own_scene_entry`.
    gates : tuple
        The adaptive controller's last stage (default :data:`GATES`; empty: none).
    pulse_episodes : int
        Its pulse episodes per candidate (:func:`pulse_success`; the benchmark's 50).

    Returns
    -------
    dict
        Controller name -> ``{"best": entry, "rows": [...], "wall_s": float}``.
    """
    out = {}
    tic = time.perf_counter()
    spec = TUNED["swing-up + LQR"]
    rows: list[dict[str, Any]] = []
    if start is None:  # the first stage with the LQR's input weight 1, as the scenes' first stage (not a stored pick's)
        start, rows = stage(env_id, spec, [{"lqr_r": FIRST_STAGE_R, **e} for e in grid()], **kwargs)
    best, refined = stage(env_id, spec, swing_up_refine_grid(start), **kwargs)
    out["swing-up + LQR"] = {"best": best, "rows": rows + refined, "wall_s": time.perf_counter() - tic}
    tic = time.perf_counter()
    spec = TUNED["adaptive swing-up + LQR"]
    best_a, rows_a = stage(env_id, spec, [{**e, "lqr_r": best["lqr_r"]} for e in grid()], **kwargs)
    if gates:  # the identification's outlier gate, on the plants and the benchmark's pulses (module docstring)
        best_a, rows_g = stage(env_id, spec, [{**best_a, "gate": g} for g in gates], pulses=pulse_episodes, **kwargs)
        rows_a = rows_a + rows_g
    out["adaptive swing-up + LQR"] = {"best": best_a, "rows": rows_a, "wall_s": time.perf_counter() - tic}
    tic = time.perf_counter()
    spec = TUNED["identified iLQR + TVLQR"]
    own = own_scene_entry(env_id, "identified iLQR + TVLQR") if planner_own is None else planner_own
    best_p, rows_p = stage(env_id, spec, [own, best_a], batched=False, **kwargs)
    out["identified iLQR + TVLQR"] = {"best": best_p, "rows": rows_p, "wall_s": time.perf_counter() - tic}
    return out


def own_scene_entry(env_id: str, name: str) -> dict[str, Any]:
    """The entry ``name`` takes on our own scene of the protocol's task (``mbs_envs/AcrobotDFKI-v1`` ->
    ``mbs_envs/Acrobot-v1``)."""
    from mbs_envs.controllers.tuned import tuned_gains

    return tuned_gains(gym.make(env_id.replace("DFKI-v1", "-v1")), name)


def tune_job(task: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """:func:`tune` of ``task["env_id"]`` (a picklable task for :func:`mbs_envs.studies.parallel.run_tasks`)."""
    return tune(task["env_id"])


# -- the catching LQR tuned for robustness, on a tuning set of the robustness axes -----------------------------------

#: the robust catch's candidates: the catching LQR's input weight ``lqr_r`` [(N m)^-2] ...
ROBUST_LQR_R = (1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)
#: ... times its catch level of ``x^T S x`` (``S`` grows with ``lqr_r``, so the levels are tried with every weight).
#: A first grid (``lqr_r`` 1-100, levels 3-100, with rates from angles) put picks at its top edges on both scenes
#: and never level 3 (the worst or near it for every policy and weight): widened upward, 3 dropped.
ROBUST_CATCH = (10.0, 30.0, 100.0, 300.0, 1000.0)
#: the tuning set: values per axis, the seed of its noise and pulses, the seed its axis values are drawn from
#: (:func:`mbs_envs.studies.dfki.sweep_parts`; the benchmark is the grid of 21 values per axis with seed 0)
ROBUST_SET = MappingProxyType({"n": 11, "seed": 1, "draw_seed": 1})


def robust_catch_grid() -> list[dict[str, float]]:
    """Every ``{"lqr_r", "catch"}`` of :data:`ROBUST_LQR_R` x :data:`ROBUST_CATCH`."""
    return [{"lqr_r": r, "catch": c} for r in ROBUST_LQR_R for c in ROBUST_CATCH]


#: the second stage: the factor on the catch level beyond which the LQR hands back to the swing-up (the hysteresis of
#: ``x^T S x``), tried with a group's picked ``lqr_r`` and ``catch``; 4, every policy's value before this stage,
#: first (so that a tie keeps it)
ROBUST_RELEASE = (4.0, 1.5, 2.0, 8.0, 16.0)


def release_grid(pick: Mapping[str, float], values: tuple[float, ...] = ROBUST_RELEASE) -> list[dict[str, float]]:
    """The second stage's candidates: ``pick`` (a group's ``{"lqr_r", "catch"}``) with each ``release`` of ``values``
    (default :data:`ROBUST_RELEASE`; a grid widened beyond a pick at its edge), in their order."""
    if not values or any(not (np.isfinite(r) and r > 1.0) for r in values):
        raise ValueError(f"values: release factors must be finite and > 1, got {values!r}")
    return [{"lqr_r": float(pick["lqr_r"]), "catch": float(pick["catch"]), "release": float(r)} for r in values]


def robust_catch(env_id: str, policies: Mapping[str, Mapping[str, Any]], groups: Mapping[str, list[str]],
                 candidates: list[dict[str, float]] | None = None, tuning_set: Mapping[str, int] = ROBUST_SET,
                 rates_from_angles: bool = True, workers: int | None = None, progress: str | None = None) -> dict[str, Any]:  # fmt: skip
    """The catching LQR's input weight and level (and, in the second stage, the hand-back factor ``release``:
    :func:`release_grid`) picked for robustness on a tuning set of the robustness axes.

    Every policy of ``policies`` (name -> a :func:`mbs_envs.studies.dfki.controller_job` task's ``spec`` and
    ``gains``) runs with every candidate (``catch_gains``, default :func:`robust_catch_grid`) the protocol's nominal
    episode and the robustness sweep on the tuning set (:data:`ROBUST_SET`: axis values drawn uniformly over the
    benchmark's ranges, noise and pulses from another seed; never the benchmark's grid). Per group of ``groups``
    (e.g. the model-based controller alone, or an agent's training seeds together: one setting for all of them) the
    pick is the candidate under which every member swings up in the nominal episode, then with the highest mean
    robustness score over the group's members on the tuning set; the first in ``candidates``' order on a tie.

    Returns
    -------
    dict
        ``"rows"``: one per policy and candidate (``policy``, ``lqr_r``, ``catch``, ``nominal_success``, each axis'
        fraction and ``score`` on the tuning set); ``"picks"``: group -> the picked candidate; ``"wall_s"``.
    """
    from .parallel import run_tasks

    candidates = robust_catch_grid() if candidates is None else [dict(c) for c in candidates]
    tic = time.perf_counter()
    parts, meta = dfki.sweep_parts(env_id, tuning_set["n"], tuning_set["seed"], draw_seed=tuning_set["draw_seed"])
    keys = [(name, k) for name in policies for k in range(len(candidates))]
    tasks = []
    for name, k in keys:
        base = {"env_id": env_id, "spec": policies[name]["spec"], "gains": policies[name].get("gains"),
                "rates_from_angles": rates_from_angles, "catch_gains": candidates[k]}  # fmt: skip
        tasks += [base] + [{**base, "part": part} for part in parts]
    results = run_tasks(dfki.controller_job, tasks, max_workers=workers, progress=progress)
    rows, per = [], 1 + len(parts)
    for i, (name, k) in enumerate(keys):
        nominal, done = results[i * per], results[i * per + 1 : (i + 1) * per]
        swept = dfki.assemble_sweep(meta, parts, [r["success"] for r in done])
        rows.append({"policy": name, **candidates[k], "nominal_success": float(nominal["criteria"]["success"]),
                     **{a: swept[a]["fraction"] for a in meta}, "score": swept["score"]["value"]})  # fmt: skip
    return {"rows": rows, "picks": pick_catches(rows, groups, candidates), "wall_s": time.perf_counter() - tic}


def pick_catches(rows: list[Mapping[str, Any]], groups: Mapping[str, list[str]], candidates: list[Mapping[str, float]]
                 ) -> dict[str, dict[str, float]]:  # fmt: skip
    """Per group, the candidate of :func:`robust_catch`'s rule from its rows: every member swings up in the nominal
    episode, then the highest mean tuning-set ``score`` over the group's members; the first in ``candidates``' order
    on a tie.

    Raises
    ------
    ValueError
        Where a group's member has no row for a candidate.
    """
    picks = {}
    for group, members in groups.items():

        def key(k: int) -> tuple[float, float]:
            mine = [
                r for r in rows if r["policy"] in members and all(r[name] == v for name, v in candidates[k].items())
            ]
            if len(mine) != len(members):
                raise ValueError(
                    f"rows: group {group!r} has {len(mine)} rows for candidate {dict(candidates[k])}, not {len(members)}"
                )
            return float(all(r["nominal_success"] for r in mine)), float(np.mean([r["score"] for r in mine]))

        picks[group] = dict(candidates[max(range(len(candidates)), key=lambda k: (key(k), -k))])
    return picks
