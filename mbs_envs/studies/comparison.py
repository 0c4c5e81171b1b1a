"""RL agents against model-based controllers (the logic of ``scripts/compare.py``).

For each scene, each policy (the model-based controllers that apply, and the
shipped SB3 agents, every training seed of each) is rolled out on the same
test seeds (:mod:`mbs_envs.studies.seeds`: disjoint from every training, validation
and tuning seed), in one batched rollout per (scene, condition, policy).
Conditions: the nominal plant; model mismatch, where the plant's masses and
lengths are scaled by ``1 +- p`` (inertias by ``(1 +- p)^3``, i.e. the same
bodies made bigger or smaller) while every controller keeps the nominal model
and the actuators keep their nominal limits; and observation noise (Gaussian,
in observation units). Policies are built inside the worker from names
(controllers from the nominal env, agents loaded from disk), so the cells can
run in processes or on Ray.

Scoring (:func:`summarize_policy`): an episode fails when it ends early (a
fall or divergence); the success rate and the error over the *successful*
episodes are reported side by side, so a failed episode never improves an
error; means carry 95 % confidence intervals from a bootstrap over training
seeds and test episodes (:func:`hierarchical_bootstrap`).
"""

from __future__ import annotations

import pathlib
import time
from typing import Any, Mapping

import gymnasium as gym
import numpy as np

from ..envs import registry
from .conditions import SCENES, Condition, conditions, listed, model_kwargs, plant_kwargs, scaled_params  # noqa: F401
from .evaluation import ERROR_METRIC, SCORING, make_controller, rollout_batch


#: the prefix of an agent's spec that makes it an RL + LQR pair (:mod:`mbs_envs.studies.handover`)
HAND_OVER = "lqr-catch:"


def load_policy(spec: str, nominal_env: gym.Env, catch_gains: Mapping[str, float] | None = None) -> Any:
    """A controller (``"module:Class"``) built on the nominal env, an agent (a folder with ``agent.zip``),
    or an agent whose swing-up the scene's LQR catches (``"lqr-catch:" + folder``; with ``catch_gains``, the
    :func:`~mbs_envs.studies.handover.hand_over` arguments ``catch``, ``release``, ``lqr_r`` in place of the tuned ones).

    Raises
    ------
    ValueError
        ``catch_gains`` for a spec that is not an RL + LQR pair.
    """
    if spec.startswith(HAND_OVER):
        from .handover import hand_over
        from .training import load_agent

        return hand_over(load_agent(pathlib.Path(spec[len(HAND_OVER) :]))[0], nominal_env, **(catch_gains or {}))
    if catch_gains:
        raise ValueError(f"catch_gains: {spec!r} is neither a controller with gains nor an RL + LQR pair")
    if ":" in spec and not pathlib.Path(spec).exists():
        return make_controller(spec, nominal_env)
    from .training import load_agent

    return load_agent(pathlib.Path(spec))[0]


#: agent folder name -> (display name, kind)
AGENT_GROUPS = {
    "ppo": ("PPO", "RL"),
    "sac": ("SAC", "RL"),
    "td3": ("TD3", "RL"),
    "sac-caps": ("SAC + CAPS", "RL"),  # SAC with the actor's smoothness regularized (mbs_envs.studies.smoothing)
    "residual-ppo": ("residual PPO", "model-based + RL"),
    "residual-sac": ("residual SAC", "model-based + RL"),
    "residual-td3": ("residual TD3", "model-based + RL"),
}
#: on the swing-up scenes every RL agent also runs as "<name> + LQR" (model-based + RL): :data:`HAND_OVER`
HAND_OVER_KIND = "model-based + RL"


def find_agents(root: pathlib.Path, scene: str) -> dict[str, list[str]]:
    """Shipped agents of a scene by algorithm: ``{"PPO": [".../ppo/seed0", ...], ...}``.

    Reads ``<root>/<id>/<algo>/seed<k>/agent.zip`` (every training seed) and
    ``<root>/<id>/<algo>/agent.zip`` (a single one); then the agents of later versions of the scene's task
    (``<root>/<name>-v<k>/...`` for a registered ``k`` above the scene's own: the same plant, start and success rule
    with another reward), named with their version (``"SAC (v2 reward)"``, :func:`version_tag`).
    """
    env_id = SCENES[scene][0].split("/")[-1]
    name_part, _, version = env_id.rpartition("-v")
    later = sorted(
        (s.id.split("/")[-1] for s in registry.SCENES
         if s.id.rpartition("-v")[0] == SCENES[scene][0].rpartition("-v")[0] and int(s.id.rpartition("-v")[2]) > int(version)),
        key=lambda i: int(i.rpartition("-v")[2]),
    )  # fmt: skip
    out: dict[str, list[str]] = {}
    for folder_name in [env_id, *later]:
        tag = "" if folder_name == env_id else version_tag(folder_name.rpartition("-")[2])
        for algo_dir in sorted(p for p in (pathlib.Path(root) / folder_name).glob("*") if p.is_dir()):
            runs = sorted(p.parent for p in algo_dir.glob("seed*/agent.zip")) or (
                [algo_dir] if (algo_dir / "agent.zip").exists() else []
            )
            if runs:
                name, kind = AGENT_GROUPS.get(algo_dir.name, (algo_dir.name.upper(), "RL"))
                out[name + tag] = [str(r) for r in runs]
                if kind == "RL" and registry.scene(scene).scoring == "swing-up":
                    out[f"{name}{tag} + LQR"] = [HAND_OVER + str(r) for r in runs]
    return out


def version_tag(version: str) -> str:
    """The suffix naming an agent trained on another version of the task: ``"v2"`` -> ``" (v2 reward)"``."""
    return f" ({version} reward)"


def kind_of(name: str) -> str:
    """``"model-based"``, ``"RL"`` or ``"model-based + RL"`` for a policy's display name (a version tag,
    :func:`version_tag`, left out)."""
    import re

    name = re.sub(r" \(v\d+ reward\)", "", name)
    for display, kind in AGENT_GROUPS.values():
        if display == name:
            return kind
        if name == f"{display} + LQR" and kind == "RL":
            return HAND_OVER_KIND
    return "model-based"


def latency_us(policy: Any, obs: np.ndarray, noise: float = 0.0, repeats: int = 200, seed: int = 0) -> float:
    """Median wall time of one ``predict`` on a single observation [us].

    With ``noise > 0`` each call sees a different observation (``obs`` plus
    Gaussian noise), as under observation noise: a policy that caches per
    observed value shows its uncached cost here.
    """
    rng = np.random.default_rng(seed)
    inputs = obs + (
        rng.normal(0.0, noise, (repeats + 1,) + obs.shape) if noise > 0 else np.zeros((repeats + 1,) + obs.shape)
    )
    inputs = inputs.astype(obs.dtype)
    policy.predict(inputs[0], deterministic=True)
    times = []
    for x in inputs[1:]:
        tic = time.perf_counter()
        policy.predict(x, deterministic=True)
        times.append(time.perf_counter() - tic)
    return float(np.median(times) * 1e6)


def evaluate_cell(task: dict[str, Any]) -> list[dict[str, Any]]:
    """All policies of one (scene, condition) on the same seeds; one row per policy, training seed and test seed.

    ``task["policies"]``: display name -> list of specs (one per training seed;
    a controller has one). Compute per action is measured in the nominal cell,
    single-threaded, on the nominal and the noisy path (:func:`latency_us`).
    """
    import torch

    torch.set_num_threads(1)
    scene, condition = task["scene"], Condition(**task["condition"])
    env_id, kwargs, _ = SCENES[scene]
    scoring = SCORING[registry.scene(scene).scoring]
    nominal = gym.make(env_id, **kwargs)
    venv = gym.make_vec(env_id, num_envs=len(task["seeds"]), vectorization_mode="vector_entry_point",
                        autoreset_mode="Disabled", **plant_kwargs(scene, condition))  # fmt: skip
    rows = []
    obs0 = nominal.reset(seed=task["seeds"][0])[0]
    for name, specs in task["policies"].items():
        for k, spec in enumerate([specs] if isinstance(specs, str) else specs):
            policy = load_policy(spec, nominal)
            episodes = rollout_batch(
                venv, policy, task["seeds"], obs_noise=condition.obs_noise, noise_seed=1, delay=condition.delay
            )
            lat = lat_noisy = float("nan")
            if condition.name == "nominal" and k == 0:
                lat, lat_noisy = (
                    latency_us(policy, obs0),
                    latency_us(policy, obs0, noise=task.get("latency_noise", 0.01)),
                )
            for seed, ep in zip(task["seeds"], episodes):
                metrics, failed = scoring(ep)
                rows.append({"scene": scene, "condition": condition.name, "policy": name, "kind": kind_of(name),
                             "train_seed": k, "seed": seed, **metrics, "failed": failed,
                             "start_peak_torque": float(np.max(np.abs(ep.u[ep.t <= 1.0]))) if len(ep.t) else float("nan"),
                             "latency_us": lat, "latency_noisy_us": lat_noisy})  # fmt: skip
    venv.close()
    return rows


def hierarchical_bootstrap(
    groups: list[np.ndarray], n_boot: int = 2000, seed: int = 0, level: float = 0.95
) -> tuple[float, float, float]:
    """Mean of the pooled values and its bootstrap confidence interval.

    Each replicate resamples the groups (training seeds) with replacement,
    then the values (test episodes) within each drawn group, and takes the
    mean of everything drawn; with one group this is the ordinary bootstrap
    over episodes. Empty groups contribute nothing (a replicate that draws
    only empty groups is skipped).

    Parameters
    ----------
    groups : list of 1-D arrays
        Values per training seed.

    Returns
    -------
    mean, low, high : float
        NaN when there are no values at all.
    """
    groups = [np.asarray(g, float).ravel() for g in groups]
    pooled = np.concatenate(groups) if groups else np.array([])
    if pooled.size == 0:
        return float("nan"), float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    G = len(groups)
    pick = rng.integers(0, G, (n_boot, G))  # replicate b, slot s: which group is drawn
    sums = np.zeros((G, n_boot, G))  # sums[j, b, s]: a resample of group j for that slot
    for j, g in enumerate(groups):
        if len(g):
            sums[j] = g[rng.integers(0, len(g), (n_boot, G, len(g)))].sum(axis=-1)
    sizes = np.array([len(g) for g in groups], float)
    b, s_ = np.meshgrid(np.arange(n_boot), np.arange(G), indexing="ij")
    total = sums[pick, b, s_].sum(axis=1)
    count = sizes[pick].sum(axis=1)
    stats = total[count > 0] / count[count > 0]
    alpha = (1 - level) / 2
    lo, hi = np.quantile(stats, [alpha, 1 - alpha])
    return float(pooled.mean()), float(lo), float(hi)


def summarize_policy(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate and errors (over successful episodes) with 95 % CIs for one policy in one condition;
    on a swing-up scene also ``return_all``, the return over every episode that did not diverge (they
    all run the full length there, so a failed one's return is not truncated and cannot flatter).

    ``rows``: one per (training seed, test episode), as from :func:`evaluate_cell`.
    """
    by_seed: dict[int, list[dict]] = {}
    for r in rows:
        by_seed.setdefault(int(r["train_seed"]), []).append(r)
    seeds = sorted(by_seed)
    success = [np.array([not r["failed"] for r in by_seed[k]], float) for k in seeds]
    out: dict[str, Any] = {"kind": rows[0]["kind"], "episodes": len(rows), "train_seeds": len(seeds)}
    out["success"], out["success_lo"], out["success_hi"] = hierarchical_bootstrap(success)
    swing_up = "time_to_swing_up" in rows[0]
    if swing_up:  # the looser success rule and the time near upright, over every episode
        for m in ("success_wide", "time_near_upright"):
            groups = [np.array([float(r[m]) for r in by_seed[k]]) for k in seeds]
            out[m], out[m + "_lo"], out[m + "_hi"] = hierarchical_bootstrap(groups)
    for m in ("rms_error_settled", "max_error", "rms_torque", "peak_torque", "return") + (
        ("time_to_swing_up", "energy_used") if swing_up else ()
    ):
        groups = [
            np.array([float(r[m]) for r in by_seed[k] if not r["failed"] and np.isfinite(float(r[m]))]) for k in seeds
        ]
        out[m], out[m + "_lo"], out[m + "_hi"] = hierarchical_bootstrap(groups)
    if swing_up:  # every episode runs its full length unless it diverged, so its return can be compared as is
        groups = [np.array([float(r["return"]) for r in by_seed[k] if not int(r.get("diverged", 0))]) for k in seeds]
        out["return_all"], out["return_all_lo"], out["return_all_hi"] = hierarchical_bootstrap(groups)
    for m in ("latency_us", "latency_noisy_us"):
        values = [float(r[m]) for r in rows if np.isfinite(float(r.get(m, float("nan"))))]
        out[m] = float(np.median(values)) if values else float("nan")
    start = [
        float(r["start_peak_torque"]) for r in rows if np.isfinite(float(r.get("start_peak_torque", float("nan"))))
    ]
    out["start_peak_torque"] = float(np.max(start)) if start else float("nan")
    return out


def best_policy(
    by_policy: dict[str, dict[str, Any]], kind: str, min_success: float = 0.95, scoring: str = "tracking"
) -> str | None:
    """The best policy of ``kind``.

    Tracking: the smallest settled error among those with success >= ``min_success``; a
    policy below the threshold is never "best", whatever its error (its error averages
    only the episodes it survived). Swing-up: the highest success rate (no threshold:
    a hard task), ties broken by the time to swing up.
    """
    metric = ERROR_METRIC[scoring]
    if scoring == "swing-up":
        names = [n for n, m in by_policy.items() if m["kind"] == kind and m["success"] > 0]
        key = lambda n: (
            -by_policy[n]["success"],
            by_policy[n][metric] if np.isfinite(by_policy[n][metric]) else np.inf,
        )  # noqa: E731
        return min(names, key=key) if names else None
    names = [
        n for n, m in by_policy.items() if m["kind"] == kind and m["success"] >= min_success and np.isfinite(m[metric])
    ]
    return min(names, key=lambda n: by_policy[n][metric]) if names else None


def verdict_against(m: dict[str, Any], ref: dict[str, Any] | None, ref_name: str = "PD") -> str:
    """How a policy's summary ``m`` compares with a reference's (PD) at one condition, on **both** metrics:
    the settled error the report ranks by and the return of the reward the agents were trained on.

    A policy "does not beat" the reference only when it loses on both; where the two metrics
    disagree the verdict says which one it wins. Winning on a metric needs at least the
    reference's success rate (a failed episode never improves a score) and a strictly better value:
    a smaller settled error, a larger return.

    Returns
    -------
    str
        ``"beats PD"``, ``"beats PD on return, not on settled error"``,
        ``"beats PD on settled error, not on return"`` or ``"does not beat PD"``.
    """
    if ref is None:
        return f"no {ref_name} to compare with"
    holds = m["success"] >= ref["success"]
    on_error = holds and m["rms_error_settled"] < ref["rms_error_settled"]
    on_return = holds and m["return"] > ref["return"]
    if on_error and on_return:
        return f"beats {ref_name}"
    if on_return:
        return f"beats {ref_name} on return, not on settled error"
    if on_error:
        return f"beats {ref_name} on settled error, not on return"
    return f"does not beat {ref_name}"
