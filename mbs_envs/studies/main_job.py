"""The main job: every scene's model-based controllers against the shipped RL agents on held-out test seeds, nominal
and perturbed, with the robustness sweep, actuator sizing, learning curves and the report (``scripts/compare.py`` is
its command line; :mod:`mbs_envs.studies.comparison` holds the evaluation of one cell).

:func:`run` takes the command line's settings (an ``argparse.Namespace`` of ``scripts/compare.py``'s options) and
writes ``summary.json``, ``episodes.csv``, ``report.md`` and the figures to ``settings.out``.
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from ..controllers import tuned
from . import comparison as cmp
from . import seeds as seed_ranges
from ..envs import registry
from ..envs.presets import PROTOCOL_IDS
from .catch import applies, catch_rows, catch_table
from .handover import TUNED_NAME as HAND_OVER_NAME
from . import scene_robustness as sr
from .parallel import run_tasks
from . import provenance
from .learning_curves import draw, training_curves
from .plotting import pyplot, save
from .sizing import actuator_sizing

ROOT = pathlib.Path(__file__).resolve().parents[2]  # the repository (the shipped agents, the reports)
KINDS = ("model-based", "RL", "model-based + RL")


def run(args: argparse.Namespace) -> dict:
    if args.plots_only:
        return replot(args.out)
    n_seeds = 3 if args.quick else args.seeds
    if not 1 <= n_seeds <= len(seed_ranges.TEST):
        raise SystemExit(f"--seeds must be in [1, {len(seed_ranges.TEST)}]")
    scenes = args.scene or list(cmp.SCENES)
    conds = cmp.conditions((0.1, 0.2, 0.3) if args.full else (0.2,), 0.01)
    args.out.mkdir(parents=True, exist_ok=True)
    seeds = seed_ranges.test_seeds(n_seeds)
    n_swing = 3 if args.quick else args.swing_up_seeds
    if not 1 <= n_swing <= len(seed_ranges.TEST):
        raise SystemExit(f"--swing-up-seeds must be in [1, {len(seed_ranges.TEST)}]")
    tasks, agents = [], {}
    for scene in scenes:
        agents[scene] = {} if args.no_agents else cmp.find_agents(args.agents, scene)
        policies = sr.policies(scene, agents[scene])
        for c in conds:
            scene_seeds = seed_ranges.test_seeds(n_swing) if scoring_of(scene) == "swing-up" else seeds
            tasks.append({"scene": scene, "condition": vars(c), "seeds": scene_seeds, "policies": policies})
    print(
        f"{len(tasks)} cells ({len(scenes)} scenes x {len(conds)} conditions), {n_seeds} test seeds each ({n_swing} on swing-up scenes)"
    )
    if args.ray is None and args.workers > 1:
        results = run_tasks(cmp.evaluate_cell, tasks, max_workers=args.workers, progress="cells")
    elif args.ray is None:
        results = [cmp.evaluate_cell(t) for t in tqdm(tasks, desc="cells")]
    else:
        results = run_tasks(cmp.evaluate_cell, tasks, ray_address=args.ray)
    rows = [r for cell in results for r in cell]
    robust, sweeps = (
        (None, None)
        if args.no_robustness
        else robustness(args, {scene: sr.policies(scene, agents[scene]) for scene in scenes})
    )
    with open(args.out / "episodes.csv", "w", newline="") as f:  # swing-up rows carry more columns
        w = csv.DictWriter(f, fieldnames=list(dict.fromkeys(k for r in rows for k in r)), restval="")
        w.writeheader()
        w.writerows(rows)
    summary = summarize(rows)
    sizing = {
        scene: sizing_tables(scene, seeds) for scene in tqdm(scenes, desc="sizing") if registry.scene(scene).sizing
    }
    curves = {scene: training_curves(agents[scene]) for scene in scenes}
    for scene in scenes:
        plot_scene(scene, summary[scene], args.out / f"comparison_{scene}.png")
    plot_learning_curves(summary, curves, args.out / "learning_curves.png")
    catch = [
        r for scene in scenes if scoring_of(scene) == "swing-up" and applies(scene) for r in catch_rows(scene, conds)
    ]
    report = make_report(summary, sizing, agents, curves, seeds, conds, n_swing, catch, robust)
    (args.out / "report.md").write_text(report)
    if sweeps:
        sr.plot(sweeps, args.out)
    config = {"test_seeds": [seeds[0], seeds[-1]], "conditions": [c.name for c in conds], "agents": portable(agents),
              "provenance": provenance.record()}  # fmt: skip
    (args.out / "summary.json").write_text(json.dumps({"config": config, "summary": summary, "sizing": sizing, "catch": catch, "robustness": robust},
                                                      indent=2, default=float))  # fmt: skip
    print(headline(summary))
    swing = swing_up_headline(summary)
    if swing:
        print(
            "\nswing-up scenes (success within 0.1 / 0.2 rad for the last 2 s; per condition: success 0.1 / 0.2 rad / time near upright [s])"
        )
        print(swing)
    if robust:
        print("\nrobustness score (mean success over the six axes; report.md has each axis)")
        for scene, by_policy in robust["scenes"].items():
            print(f"  {scene}: " + ", ".join(f"{name} {r['score']:.2f}" for name, r in by_policy.items()))
    print(f"written to {args.out}/report.md, episodes.csv, summary.json, learning_curves.png, comparison_<scene>.png"
          + (" and robustness_<scene>.png" if robust else ""))  # fmt: skip
    return {"summary": summary, "rows": rows, "sizing": sizing, "robustness": robust}


def replot(out: pathlib.Path) -> dict:
    """``--plots-only``: each scene's comparison figure drawn again from ``out/summary.json``."""
    summary = json.loads((out / "summary.json").read_text())["summary"]
    for scene in tqdm(summary, desc="plots"):
        plot_scene(scene, summary[scene], out / f"comparison_{scene}.png")
    print(f"written to {out}/comparison_<scene>.png")
    return {"summary": summary}


def robustness(args: argparse.Namespace, policies: dict[str, dict[str, list[str]]]) -> tuple[dict, dict]:
    """The six-axis robustness sweep of every policy (``mbs_envs/studies/scene_robustness.py``; ``scripts/robustness.py``
    runs it with more values): per scene and policy the success fractions, the score and the wall times; and the
    sweeps themselves (for the plots)."""
    import time

    n, pulses = (2, 2) if args.quick else (args.robustness_values, args.robustness_pulses)
    jobs = sr.tasks(policies, n, args.robustness_seeds, pulses)
    tic = time.perf_counter()
    results = run_tasks(
        sr.sweep_job, jobs, ray_address=args.ray, max_workers=args.workers, progress="robustness sweeps"
    )
    _, summary, sweeps = sr.collect(jobs, results)
    return {"values_per_axis": n, "seeds_per_value": args.robustness_seeds, "pulse_episodes": pulses, "wall_s": time.perf_counter() - tic,
            "scenes": summary}, sweeps  # fmt: skip


def portable(obj: Any) -> Any:
    """``obj`` with every string path inside this repository made relative to its root (``agents/...``), so a
    committed ``summary.json`` holds no path of the machine that made it; other strings unchanged."""
    if isinstance(obj, dict):
        return {k: portable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [portable(v) for v in obj]
    if isinstance(obj, str):
        return obj.replace(str(ROOT) + "/", "")
    return obj


def summarize(rows: list[dict]) -> dict:
    """``summary[scene][condition][policy]`` = :func:`mbs_envs.studies.comparison.summarize_policy` of its rows."""
    grouped: dict = {}
    for r in rows:
        grouped.setdefault(r["scene"], {}).setdefault(r["condition"], {}).setdefault(r["policy"], []).append(r)
    return {scene: {cond: {p: cmp.summarize_policy(rs) for p, rs in by_p.items()} for cond, by_p in by_c.items()}
            for scene, by_c in grouped.items()}  # fmt: skip


def ci(m: dict, key: str, digits: int = 3) -> str:
    """``mean [lo, hi]`` of a summary entry, or ``-``."""
    if not np.isfinite(m.get(key, float("nan"))):
        return "-"
    return f"{m[key]:.{digits}g} [{m[key + '_lo']:.{digits}g}, {m[key + '_hi']:.{digits}g}]"


def success(m: dict, key: str = "success") -> str:
    return f"{m[key]:.0%}" + ("" if m[key] == 1 else f" [{m[key + '_lo']:.0%}, {m[key + '_hi']:.0%}]")


def rl_label(name: str, verdict: str) -> str:
    """An agent's name in the headline with its verdict against PD on both metrics
    (:func:`mbs_envs.studies.comparison.verdict_against`): bold only where it loses on both."""
    if verdict.startswith("does not beat"):
        return f"{name} (**{verdict}**)"
    return name if verdict == "beats PD" else f"{name} ({verdict})"


def pd_of(by_policy: dict) -> dict | None:
    """The PD row of a condition (``PD steering`` on the disk), if any."""
    return by_policy.get("PD") or by_policy.get("PD steering")


def scoring_of(scene: str) -> str:
    return registry.scene(scene).scoring


def swing_up_headline(summary: dict) -> str:
    """Best policy per side on the swing-up scenes (and every model-based controller): success (upright for
    the last 2 s), time to swing up, energy, at nominal and under each perturbation."""
    scenes = [s for s in summary if scoring_of(s) == "swing-up"]
    if not scenes:
        return ""
    conds = [c for c in summary[scenes[0]] if c != "nominal"]
    lines = ["| scene | side | policy | nominal: success 0.1 rad | success 0.2 rad | near upright [s] | time to swing up [s] | energy used [J] | "
             + " | ".join(f"{c}" for c in conds) + " |", "|---|---|---|---|---|---|---|---|" + "---|" * len(conds)]  # fmt: skip
    for scene in scenes:
        by_cond = summary[scene]
        nominal = by_cond["nominal"]
        for kind in KINDS:
            if not any(m["kind"] == kind for m in nominal.values()):
                continue
            name = cmp.best_policy(nominal, kind, scoring="swing-up")
            if name is None:
                lines.append(f"| {scene} | best {kind} | (none swings up) |" + " |" * (5 + len(conds)))
                continue
            # the model-based side shows every controller (the simple baseline beside the stronger ones), best first
            others = [n for n, m in nominal.items() if m["kind"] == kind and n != name] if kind == "model-based" else []
            for label, shown in [(f"best {kind}", name)] + [(kind, n) for n in others]:
                m = nominal[shown]
                cells = [
                    success(m),
                    success(m, "success_wide"),
                    ci(m, "time_near_upright"),
                    ci(m, "time_to_swing_up"),
                    ci(m, "energy_used"),
                ]
                cells += [f"{by_cond[c][shown]['success']:.0%} / {by_cond[c][shown]['success_wide']:.0%} / "
                          f"{by_cond[c][shown]['time_near_upright']:.1f}" for c in conds]  # fmt: skip
                lines.append(f"| {scene} | {label} | {shown} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def headline(summary: dict) -> str:
    """Best policy per side and scene: settled error and success at nominal and +-20 %, return, compute.

    An RL or residual agent that does not beat PD at the nominal plant is
    shown, but marked as such: it is not a "best" of its side by the rule of
    only the strongest there is.
    """
    lines = ["| scene | side | policy | nominal: error [95 % CI] | success | -20 %: error | success | +20 %: error | success | "
             "nominal: return [95 % CI] | us per action (noisy obs) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for scene, by_cond in summary.items():
        if scoring_of(scene) != "tracking":
            continue
        nominal = by_cond["nominal"]
        for kind in KINDS:
            if not any(m["kind"] == kind for m in nominal.values()):
                continue
            name = cmp.best_policy(nominal, kind)
            if name is None:
                lines.append(f"| {scene} | best {kind} | (none with >= 95 % success) | | | | | | | | |")
                continue
            m = nominal[name]
            label = name if kind == "model-based" else rl_label(name, cmp.verdict_against(m, pd_of(nominal)))
            cells = [f"{ci(m, 'rms_error_settled')} | {success(m)}"]
            for c in ("mismatch -20%", "mismatch +20%"):
                cells.append(
                    f"{ci(by_cond[c][name], 'rms_error_settled')} | {success(by_cond[c][name])}"
                    if c in by_cond
                    else "- | -"
                )
            cells.append(ci(m, "return"))
            lines.append(
                f"| {scene} | best {kind} | {label} | "
                + " | ".join(cells)
                + f" | {m['latency_us']:.0f} ({m['latency_noisy_us']:.0f}) |"
            )
    return "\n".join(lines)


def two_metrics(summary: dict) -> str:
    """Per scene, the best policy by settled error and the best by episode return (nominal, >= 95 % success)."""
    lines = [
        "| scene | best by settled error (t >= 1 s) | best by return (the reward the agents maximize) |",
        "|---|---|---|",
    ]
    for scene, by_cond in summary.items():
        if scoring_of(scene) != "tracking":
            continue
        ok = {n: m for n, m in by_cond["nominal"].items() if m["success"] >= 0.95 and np.isfinite(m["return"])}
        if not ok:
            continue
        by_err = min(ok, key=lambda n: ok[n]["rms_error_settled"])
        by_ret = max(ok, key=lambda n: ok[n]["return"])
        lines.append(
            f"| {scene} | {by_err}: {ci(ok[by_err], 'rms_error_settled')} | {by_ret}: {ci(ok[by_ret], 'return')} |"
        )
    return "\n".join(lines)


def sizing_tables(scene: str, seeds: list[int]) -> dict:
    """Inverse-dynamics sizing along the references of all ``seeds`` (5 s each): max and 95th percentile per drive."""
    env_id, kwargs, _ = cmp.SCENES[scene]
    env = gym.make(env_id, **kwargs).unwrapped
    per_seed = []
    for seed in seeds:
        env.reset(seed=seed)
        t_final = gym.spec(env_id).max_episode_steps * env.dt
        s = actuator_sizing(env.model, env.reference, t_final=t_final, dt=2e-3, branch=getattr(env, "branch", 1))
        per_seed.append(s)
    peak_t = np.array([s.peak_torque for s in per_seed])
    rms_t = np.array([s.rms_torque for s in per_seed])
    peak_p = np.array([s.peak_power for s in per_seed])
    drives = [{"drive": j, "peak_torque_max": float(peak_t[:, j].max()), "peak_torque_p95": float(np.percentile(peak_t[:, j], 95)),
               "rms_torque_max": float(rms_t[:, j].max()), "peak_power_max": float(peak_p[:, j].max()),
               "peak_power_p95": float(np.percentile(peak_p[:, j], 95))} for j in range(peak_t.shape[1])]  # fmt: skip
    out = {"seeds": [seeds[0], seeds[-1]], "drives": drives, "torque_limit": env.u_max.tolist()}
    if per_seed[0].peak_joint_force is not None:
        f = np.array([s.peak_joint_force for s in per_seed]).max(axis=0)
        out["peak_joint_force_N"] = dict(
            zip(["O (ground-crank)", "A (crank-coupler)", "B (coupler-rocker)", "C (rocker-ground)"], f.tolist())
        )
    return out


def plot_scene(scene: str, by_cond: dict, path: pathlib.Path) -> None:
    """Per condition and policy, means with 95 % CIs: on the tracking scenes the settled error of the successful
    episodes (log axis: errors span decades), the success rate written where it is below 100 %; on the swing-up
    scenes two panels, the success rate at 0.1 rad and the time to swing up of the successful episodes (linear axes
    from zero: the times differ by seconds, not decades). A policy without a successful episode has no error or
    time: its success is written at the foot of the axis, inside it, so no label can stretch the figure."""
    plt = pyplot()
    swing_up = scoring_of(scene) == "swing-up"
    conds = list(by_cond)
    policies = [p for p in by_cond["nominal"] if p != "no control"]
    x = np.arange(len(conds))
    width = 0.8 / len(policies)
    key = cmp.ERROR_METRIC[scoring_of(scene)]
    if swing_up:
        fig, (ax_s, ax) = plt.subplots(2, 1, figsize=(12, 7), sharex=True)
        bars(ax_s, x, width, policies, [[by_cond[c][p] for c in conds] for p in policies], "success", scale=100.0)
        ax_s.set_ylim(0, 125)  # room for the legend above 100 %
        ax_s.set_yticks(np.arange(0, 101, 20))
        ax_s.set_ylabel("success at 0.1 rad [%]")
        ax_s.set_title(f"{scene}: mean and 95 % CI over test episodes (and training seeds)")
        ax_s.legend(fontsize=7, ncol=len(policies), loc="upper center")
    else:
        fig, ax = plt.subplots(figsize=(12, 4.5))
        ax.set_title(
            f"{scene}: mean and 95 % CI over test episodes (and training seeds); labels: success rate if < 100 %"
        )
    bars(ax, x, width, policies, [[by_cond[c][p] for c in conds] for p in policies], key, label_success=not swing_up)
    if swing_up:
        ax.set_ylim(bottom=0.0)
        ax.set_ylabel("time to swing up, successful episodes [s]")
    else:
        ax.set_yscale("log")
        low, high = ax.get_ylim()
        ax.set_ylim(low, high * 4)  # room for the success labels above the highest bars
        ax.set_ylabel("settled RMS error, successful episodes [rad]")
        ax.legend(fontsize=7, ncol=2)
    ax.set_xticks(x + 0.4 - width / 2, conds, fontsize=8)
    save(fig, path)


def bars(ax: Any, x: np.ndarray, width: float, policies: list[str], cells: list[list[dict]], key: str, scale: float = 1.0,
         label_success: bool = False) -> None:  # fmt: skip
    """One bar per policy and condition: ``cells[k][i][key]`` (times ``scale``) with its 95 % CI; a missing (NaN) value
    draws no bar. With ``label_success``, the success rate is written above each bar where it is below 100 %, and
    at the foot of the axis (axes coordinates) where there is no bar."""
    foot = ax.get_xaxis_transform()  # x in data, y in axes fractions
    for k, (name, m) in enumerate(zip(policies, cells)):
        y = np.array([v[key] for v in m], float) * scale
        err = np.array([[v[key] - v[key + "_lo"], v[key + "_hi"] - v[key]] for v in m], float).T * scale
        xs = x + k * width
        ax.bar(xs, y, width, yerr=err, capsize=2, label=name, color=f"C{k}")
        if not label_success:
            continue
        for xi, yi, v in zip(xs, y, m):
            if v["success"] >= 1:
                continue
            text = f"{v['success']:.0%}"
            if np.isfinite(yi):
                ax.annotate(text, (xi, v[key + "_hi"] * scale), xytext=(0, 3), textcoords="offset points", fontsize=6, ha="center",
                            va="bottom", rotation=90)  # fmt: skip
            else:
                ax.text(
                    xi, 0.02, text, transform=foot, fontsize=6, ha="center", va="bottom", rotation=90, color=f"C{k}"
                )


def plot_learning_curves(summary: dict, curves: dict, path: pathlib.Path) -> None:
    """Per scene: validation error of each algorithm (mean, range over training seeds) against env steps and wall time;
    on the swing-up scenes the validation success rate (the error is undefined until an episode succeeds, and agents
    of different task versions train on different rewards, so their returns do not compare)."""
    scenes = [s for s in summary if curves.get(s)]
    if not scenes:
        return
    plt = pyplot()
    fig, axes = plt.subplots(len(scenes), 2, figsize=(12, 3.6 * len(scenes)), squeeze=False)
    for row, scene in zip(axes, scenes):
        swing_up = scoring_of(scene) == "swing-up"
        metric = "success" if swing_up else "rms_error_settled"
        for name, c in curves[scene].items():
            for ax, key in zip(row, ("timesteps", "train_wall_s")):
                draw(ax, name, c["runs"], metric, key)
        for ax in row:
            for name, m in summary[scene]["nominal"].items():
                value = m.get("success") if swing_up else m["rms_error_settled"]
                if m["kind"] == "model-based" and value is not None and np.isfinite(value) and name != "no control":
                    ax.axhline(value, ls="--", lw=1, color="gray")
                    ax.annotate(f" {name}", (1.0, value), xycoords=("axes fraction", "data"), fontsize=7, va="center")
            ax.set_yscale("linear" if swing_up else "log")
            ax.set_ylabel("validation success" if swing_up else "validation RMS error [rad]")
            ax.legend(fontsize=7)
            ax.set_title(scene, loc="left", fontsize=10, fontweight="bold")
        row[0].set_xlabel("env steps")
        row[1].set_xlabel("training wall time [s] (one thread)")
    fig.suptitle("Learning curves: validation error, on the swing-up scenes the success rate (mean, band = range over training seeds); "
                 "dashed: model-based controllers on the test seeds",
                 fontsize=10)  # fmt: skip
    save(fig, path, rect=(0, 0, 1, 1 - 0.5 / fig.get_figheight()))  # room for the two-line title


def make_report(
    summary: dict,
    sizing: dict,
    agents: dict,
    curves: dict,
    seeds: list[int],
    conds: list,
    n_swing: int | None = None,
    catch: list | None = None,
    robust: dict | None = None,
) -> str:
    tuned_record = json.loads(tuned.PATH.read_text()) if tuned.PATH.exists() else {}
    L = ["# RL agents against model-based controllers", ""]
    swing_seeds = f"; on the swing-up scenes {n_swing}, seeds 0-{n_swing - 1}" if n_swing else ""
    L.append(f"**Protocol.** {len(seeds)} test episodes per policy and condition, seeds {seeds[0]}-{seeds[-1]}{swing_seeds} (the same starts and "
             "references for every policy). Test seeds are disjoint from every other seed used: training members start from "
             f"{seed_ranges.TRAINING_BASE} + 1000 k + i (run k, member i), learning curves use validation seeds "
             f"{seed_ranges.VALIDATION[0]}-, gain tuning uses seeds {seed_ranges.TUNING[0]}- (`mbs_envs/studies/seeds.py`). "
             "An episode fails when it ends early (fall or divergence); errors (Euclidean norm over tracked joints, the disk: its "
             "heading error, RMS after the first second) average the *successful* episodes only and stand beside the success "
             "rate, and a policy is \"best\" on its side only with >= 95 % success at the nominal plant. Brackets: 95 % confidence "
             "intervals from a bootstrap over training seeds and test episodes. Mismatch: the plant's masses and lengths "
             "x (1 +- p), inertias x (1 +- p)^3, controllers and actuator limits nominal; noise: Gaussian, std 0.01 on every "
             "observation entry; input delay: the plant applies the action chosen one control step earlier (10 ms; zero at the first step). On the disk, scaling `r` also moves the critical spin `sqrt(g / 3r)` against which each "
             "episode's commanded spin is drawn (0.3-2 times the plant's), so mismatch changes the task as well as the plant. "
             "Compute per action: one `predict` on one observation, one thread, median of 200; in brackets with a fresh noisy "
             "observation at every call. Training wall times are as each run recorded them (one torch thread, evaluation "
             "excluded); runs may have shared the machine with other runs, so they bound the cost from above.")  # fmt: skip
    L += ["", f"Run on: {provenance.summary_line(provenance.record())} (`mbs_envs/studies/provenance.py`: what the numbers "
          "depend on besides the code; a re-run on the same stack reproduced every non-timing value).", ""]  # fmt: skip
    L += ["", "## Headline", "", headline(summary), ""]
    if swing_up_headline(summary):
        L += ["**Swing-up scenes** (Acrobot-v1, Pendubot-v1: one motor, 15 s episodes; CartPoleSwingUp-v0: the cart's force, "
              "10 s, leaving the rail ends the episode; an episode succeeds when every angle (both joints; the pole) stays within "
              "0.1 rad of upright for its last 2 s, and at 0.2 rad when they stay within 0.2 rad; near upright: the seconds "
              "with all within 0.3 rad, anywhere in the episode; time to swing up: from when it stays within 0.1 rad; energy: "
              "the motor's work int |u v_driven| dt; time and energy over the successful episodes; best = highest success, "
              "then time; each perturbed cell: success at 0.1 rad / at 0.2 rad / seconds near upright):", "",
              swing_up_headline(summary), ""]  # fmt: skip
    if catch:
        L += ["**What physics allows** (the arm's swing-up scenes; not yet computed for the derived cart-pole): along each coordinate about upright (the others zero), the largest "
              "offset from which the scene's LQR (its nominal gains, the balancing part of swing-up + LQR) brings the "
              "condition's plant back within 0.1 rad in 5 s, simulated on the control map, beside the bound of the torque "
              "limit on that plant's linearization (no input brings back an unstable mode w^T x beyond |w^T B| u_max / lambda, "
              "shrunk by e^(lambda delay) with the input delay; `mbs_envs/studies/catch.py`, `controllers/region.py`). "
              "An LQR catch far below the bound is the controller's limit, not physics'. With observation noise, the "
              "noise-floor column is the smallest stationary standard deviation of each angle about upright that any causal controller "
              "achieves on the linearization (the LQG optimum as its input weight vanishes, `controllers.region.noise_floor`): "
              "no controller holds the angle with a smaller spread, so a tolerance of two such deviations or less fails often "
              "whatever the controller. \"LQG holds\": the share of windows of the success rule (both angles within 0.1 rad "
              "for 2 s) that the best of 80 LQG controllers (input weights 1e-9 to 1e-2, the first angle weighted 0.01 to 1e4 "
              "times the second, the rates 1e-12 to 10; input unbounded, the state estimated by the Kalman filter) holds "
              "on the linearization once stationary, 2,000 windows each, the same for every controller "
              "(`controllers.region.lqg_hold_share`; an estimate of what a controller that knows the plant achieves, "
              "not a bound), and in brackets from the most favourable start for those controllers: the window beginning "
              "exactly upright with an exact estimate (for such a fixed linear controller no start holds more windows, by "
              "Anderson's theorem: the window's states are jointly Gaussian, their covariance independent of the start; "
              "a filter that trusted an accurate estimate at the window's start more than the stationary one could "
              "hold more). A controller that is not linear can also hold more: \"planner's hold holds\" is the share "
              "the hold of identified iLQR + TVLQR (on the nominal model's linearization: the elbow steers the arm's "
              "unstable zero dynamics, the mode `z` of the shoulder-elbow combination the input does not reach, asked "
              "at most 0.0975 rad off upright, `controllers.region.zero_dynamics_input`; past what that reach can pull "
              "back it rescues the arm with a reach of 0.2 rad, `controllers.region.rescuing`) holds on the same "
              "linearization, stationary, with the steady Kalman filter and the torque limit "
              "(`mbs_envs.studies.catch.planner_hold_share`, 2,000 windows; blank where the planner uses no hold: on the "
              "pendubot its upright LQR holds every window). Neither share is a "
              "bound on what physics allows under noise; the noise floor is:", "", catch_table(catch), ""]  # fmt: skip
    L += [
        "**Two metrics.** The error columns are the tracking error after the first second; the agents were trained on the "
        "reward, whose return also counts the start transient and the effort: per step "
        "`-(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |a|^2)` with `(w_e, w_de, w_u) = (1, 0.1, 1e-3)` on the joint-tracking "
        "scenes (`a` the normalized action), the disk's heading, lean, spin and effort terms (`mbs_envs/envs/rolling_disk.py`). "
        'The two can disagree; an agent is marked "does not beat PD" only where it loses on both:',
        "",
        two_metrics(summary),
        "",
    ]
    L += ["![learning curves](learning_curves.png)", ""]
    if tuned_record:
        L += ["## Model-based gains: how they were chosen", "", "```", (tuned_record.get("procedure") or "").strip(), "```", "",
              f"Tuning seeds {tuned_record['tuning_seeds'][0]}-{tuned_record['tuning_seeds'][1]}, conditions {', '.join(tuned_record['conditions'])}. "
              "Score: failure rate, then mean settled error over the conditions. Commands: "
              + "; ".join(sorted({f"`{c}`" for by_c in tuned_record["scores"].values() for sc in by_c.values()
                                  for c in (sc.get("first_stage", {}).get("command"), sc.get("command")) if c})) + ".", "",
              "(The DFKI protocol ids' entries are tuned and scored on the protocol: `scripts/dfki.py --tune`, `docs/figures/dfki_tuning/`.)", "",
              "| env | controller | tuned gains | tuned: failures / error | pre-tuning default | pre-tuning: failures / error | at grid edge |", "|---|---|---|---|---|---|---|"]  # fmt: skip
        pairs = []
        protocol = {
            entry[0] for entry in PROTOCOL_IDS
        }  # tuned on the DFKI protocol (scripts/dfki.py --tune), scored there
        for env_id, by_c in tuned_record["gains"].items():
            if env_id in protocol:
                continue
            for name, entry in by_c.items():
                sc = tuned_record["scores"][env_id][name]
                if name == HAND_OVER_NAME:  # scored differently: below
                    pairs.append(f"- {env_id}: `{json.dumps(entry)}`, success {sc['success']:.0%} over {len(sc['agents'])} agents x "
                                 f"(nominal, +-20 %) on the tuning seeds (`{sc['command']}`).")  # fmt: skip
                    continue
                L.append(f"| {env_id} | {name} | `{json.dumps(entry)}` | {sc['tuned']['failure_rate']:.0%} / {sc['tuned']['error']:.3g} | "
                         f"`{json.dumps(sc['pre_tuning']['entry'])}` | {sc['pre_tuning']['failure_rate']:.0%} / {sc['pre_tuning']['error']:.3g} | "
                         f"{', '.join(sc.get('at_grid_edge') or []) or 'no'} |")  # fmt: skip
        L.append("")
        if pairs:
            L += ["**RL + LQR catch level** (where an agent hands over to the LQR; a grid of levels of x^T S x scored by every "
                  "shipped agent's success, `scripts/tune_handover.py`, `docs/figures/tune_handover/`; a scene without an entry "
                  "uses the swing-up + LQR's own level, none having made any agent succeed):", ""] + pairs + [""]  # fmt: skip
    L += agent_tuning_section(ROOT / "docs" / "figures" / "tune_agent")
    for scene, by_cond in summary.items():
        swing_up = scoring_of(scene) == "swing-up"
        L += [f"## {scene}", "", f"![{scene}](comparison_{scene}.png)", ""]
        if swing_up:
            L.append("| condition | policy | success | success 0.2 rad | near upright [s] | time to swing up [s] | energy used [J] | RMS torque | "
                     "peak torque | return, all episodes | us/action (noisy) |")  # fmt: skip
            L.append("|---|---|---|---|---|---|---|---|---|---|---|")
        else:
            L.append(
                "| condition | policy | success | RMS error t>=1 s | max error | RMS torque | peak torque | return | us/action (noisy) |"
            )
            L.append("|---|---|---|---|---|---|---|---|---|")
        for cond, by_policy in by_cond.items():
            for name, m in by_policy.items():
                lat = f"{m['latency_us']:.0f} ({m['latency_noisy_us']:.0f})" if np.isfinite(m["latency_us"]) else ""
                cells = (f"{success(m, 'success_wide')} | {ci(m, 'time_near_upright')} | {ci(m, 'time_to_swing_up')} | {ci(m, 'energy_used')}"
                         if swing_up else f"{ci(m, 'rms_error_settled')} | {m['max_error']:.3g}")  # fmt: skip
                L.append(f"| {cond} | {name} | {success(m)} | {cells} | {m['rms_torque']:.3g} | "
                         f"{m['peak_torque']:.3g} | {ci(m, 'return_all') if swing_up else format(m['return'], '.1f')} | {lat} |")  # fmt: skip
        L.append("")
        best_mb = cmp.best_policy(by_cond["nominal"], "model-based", scoring=scoring_of(scene))
        pd = pd_of(by_cond["nominal"])
        for name, c in curves.get(scene, {}).items():
            m = by_cond["nominal"][name]
            if swing_up:
                mb = by_cond["nominal"].get(best_mb) if best_mb else None
                better = mb is None or (m["success"], -np.nan_to_num(m["time_to_swing_up"], nan=np.inf)) > (
                    mb["success"],
                    -np.nan_to_num(mb["time_to_swing_up"], nan=np.inf),
                )
                verdict = (
                    f"{'beats' if better else '**does not beat**'} {best_mb or 'the model-based controller'} at the nominal plant "
                    f"(success {m['success']:.0%} against {mb['success']:.0%})"
                    if mb
                    else "no model-based controller swings up"
                )
                if mb and not better and m["return_all"] > mb["return_all"]:  # the reward and the task disagree: say so
                    verdict += (
                        f", though its mean return is higher ({m['return_all']:.0f} against {mb['return_all']:.0f}): "
                        "the reward pays for height along the way, and the agent gathers it without holding the arm upright"
                    )
            else:
                verdict = cmp.verdict_against(m, pd) + " at the nominal plant (settled error and return)"
                if verdict.startswith("does not beat"):
                    verdict = f"**{verdict}**"
            L.append(f"- {name}: {len(c['runs'])} training seed(s), {verdict}.")
            for r in c["runs"]:
                before = (
                    ""
                    if not r.get("init")
                    else f", after {r['init']['steps']:,} on {r['init']['env_id']} (`{r['init']['from']}`)"
                )
                L.append(
                    f"  - seed {r['seed']}: `{r['command']}` ({r['steps']:,} env steps{before}, {r['wall']:.0f} s of training)"
                )
        if best_mb:
            L.append(f"- Best model-based at the nominal plant: {best_mb}.")
        L.append("")
    if robust:
        L += ["## Robustness (six axes)", "", sr.describe(robust["values_per_axis"], robust["seeds_per_value"], robust["pulse_episodes"])
              + f" Sweep wall time {robust['wall_s']:.0f} s. `python scripts/robustness.py --out DIR` runs it with more values "
              "(`docs/figures/robustness/`).", ""]  # fmt: skip
        for scene, by_policy in robust["scenes"].items():
            L += [f"### {scene}", "", *sr.markdown_table(by_policy), "", f"![{scene}](robustness_{scene}.png)", ""]
    if sizing:
        L += [f"## Actuator sizing (inverse dynamics along the references of the {len(seeds)} test seeds, whole episodes)", "",
              "The torque the reference motion itself needs; the start transient (correcting the initial error) comes on top "
              "and is listed separately: the largest torque computed torque applied in the first second of any nominal test episode.", ""]  # fmt: skip
        for scene, s in sizing.items():
            transient = summary[scene]["nominal"].get("computed torque", {}).get("start_peak_torque", float("nan"))
            L += [
                f"### {scene}",
                "",
                "| drive | peak torque: max / 95th pct [N m] | RMS torque max [N m] | peak power: max / 95th pct [W] | torque limit [N m] |",
                "|---|---|---|---|---|",
            ]
            for d in s["drives"]:
                L.append(f"| {d['drive'] + 1} | {d['peak_torque_max']:.3g} / {d['peak_torque_p95']:.3g} | {d['rms_torque_max']:.3g} | "
                         f"{d['peak_power_max']:.3g} / {d['peak_power_p95']:.3g} | {s['torque_limit'][d['drive']]:.3g} |")  # fmt: skip
            L.append("")
            L.append(f"Start transient (computed torque, t <= 1 s, nominal, any drive): peak {transient:.3g} N m.")
            if "peak_joint_force_N" in s:
                L.append(
                    "Peak joint reaction forces over all seeds [N] (from the Lagrange multipliers): "
                    + ", ".join(f"{k} {v:.3g}" for k, v in s["peak_joint_force_N"].items())
                )
            L.append("")
    return "\n".join(L) + "\n"


def shipped_settings(agents: pathlib.Path, env_id: str, algo: str) -> dict | None:
    """The settings of the shipped ``algo`` agents on ``env_id`` (their SB3 hyperparameters and
    ``action_repeat``, as a search's candidates name them; seed 0's record), None if none is shipped."""
    folder = agents / env_id.split("/")[-1] / algo
    path = next((p for p in (folder / "config.json", folder / "seed0" / "config.json") if p.exists()), None)
    if path is None:
        return None
    record = json.loads(path.read_text())
    return {**record.get("hyperparameters", {}), "action_repeat": record.get("action_repeat", 1)}


def is_shipped(candidate: dict, shipped: dict | None) -> bool:
    """Whether the shipped agents train with ``candidate``'s settings (a candidate without an action repeat has 1)."""
    return shipped is not None and all(shipped.get(k) == v for k, v in {"action_repeat": 1, **candidate}.items())


def agent_tuning_section(folder: pathlib.Path, agents: pathlib.Path = ROOT / "agents") -> list[str]:
    """The report's account of the agents' hyperparameter searches (``scripts/tune_agent.py`` results
    committed under ``folder/<name>/tuning.json``); empty without any. "picked" is each search's
    choice, "shipped" whether the agents under ``agents`` train with that candidate's settings."""
    records = [json.loads(p.read_text()) for p in sorted(folder.glob("*/tuning.json"))]
    if not records:
        return []
    L = ["## RL hyperparameters: how they were chosen", "",
         "The agents train with the project's defaults (`mbs_envs/studies/training.py: hyperparameters`) unless their "
         "command sets `--hyper`. Where a search was run (`scripts/tune_agent.py`, `mbs_envs/studies/agent_tuning.py`), "
         "each candidate trained once (training seed 0, the budget below) and was ranked on the validation seeds by failure "
         "rate, then the scene's error, then return; a later search may start from an earlier one's pick, and the "
         "\"shipped\" column marks the candidate the shipped agents train with. `action_repeat` K holds each action for K "
         "control steps (`--action-repeat`: the agent decides every K dt and is evaluated the same way); steps count "
         "control steps whatever K. Results and learning curves: `docs/figures/tune_agent/`.", "",
         "| env | algorithm | steps per candidate | candidate | failures | return | training [s] | picked | shipped |",
         "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for rec in records:
        shipped = shipped_settings(agents, rec["env_id"], rec["algo"])
        for row in rec["rows"]:
            L.append(f"| {rec['env_id']} | {rec['algo']} | {rec['steps']:,} | `{json.dumps(row['hyper'])}` | {row['failure_rate']:.0%} | "
                     f"{row['return']:.1f} | {row['train_wall_s']:.0f} | {'yes' if row['hyper'] == rec['best'] else ''} | "
                     f"{'yes' if is_shipped(row['hyper'], shipped) else ''} |")  # fmt: skip
    return L + [""]
