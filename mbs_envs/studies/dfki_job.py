"""The DFKI protocol's study: every swing-up controller and shipped agent on the protocol ids, the simulation-v2 score and the robustness-v2 sweep, their tuning on the protocol, the report and the figures (``scripts/dfki.py`` is its command line)."""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import time

import gymnasium as gym
import numpy as np


import mbs_envs  # noqa: F401
from .. import validation as check
from ..envs.presets import PROTOCOL_IDS
from ..envs.registry import PROTOCOL_CONTROLLERS, SWING_UP_CONTROLLERS

#: every model-based controller run on the protocol
MODEL_BASED = {**SWING_UP_CONTROLLERS, **PROTOCOL_CONTROLLERS}
from . import dfki
from .parallel import run_tasks
from .robustness import plot_success
from .learning_curves import draw, training_curves
from .plotting import pyplot, save
from .provenance import command_line


SCENES = {entry[0].split("/")[1].replace("DFKI-v1", ""): entry[0] for entry in PROTOCOL_IDS}
#: what ``--rates-from-angles`` appends to each policy's name
RATES_SUFFIX = " (rates from angles)"
#: what ``--robust-catch`` appends to each policy's name, and to its name for the entry in ``controllers/tuned.json``
CATCH_SUFFIX = " (robust catch)"
CRITERIA = ("swingup_time", "energy", "tau_cost", "tau_smoothness", "velocity_cost")
#: the most members of a default part of a model-based controller's sweep (:func:`sweep_parts_of`)
PART_MEMBERS = 32


def run(args: argparse.Namespace) -> dict:
    args.out.mkdir(parents=True, exist_ok=True)
    scenes = args.scene or sorted(SCENES)
    rows, sweeps = [], {}
    specs = {s: policies(s, None if args.no_agents else args.agents) for s in scenes}
    jobs = [(s, n) for s in scenes for n in specs[s]
            if (not args.controller or n in args.controller) and not (args.no_controllers and n in MODEL_BASED)]  # fmt: skip
    if not jobs:
        raise SystemExit("dfki.py: no controller or agent matches --controller")
    if args.robust_catch:
        catches = {(s, n): robust_catch_entry(s, n) for s, n in jobs}
        skipped = [f"{n} ({s})" for (s, n), c in catches.items() if c is None]
        jobs = [j for j in jobs if catches[j] is not None]
        if skipped:
            print(
                "--robust-catch: no catch tuned for robustness (--tune-robust-catch --write), not run: "
                + ", ".join(skipped)
            )
        if not jobs:
            raise SystemExit("dfki.py: no policy has a catch tuned for robustness (run --tune-robust-catch --write)")
    gains = {(s, n): protocol_gains(s, n) for s, n in jobs}
    base = [{"env_id": SCENES[s], "spec": specs[s][n], "gains": gains[s, n][0], "rates_from_angles": args.rates_from_angles,
             **({"catch_gains": catches[s, n]} if args.robust_catch else {})} for s, n in jobs]  # fmt: skip
    tasks = list(base)  # the protocol's episode of each, then the parts of every sweep: one pool keeps every core busy
    owner: list[int] = []
    metas: dict[int, dict] = {}
    if args.robustness:
        parts, metas = sweep_parts_of(jobs, args.values, args.seed, args.workers or os.cpu_count() or 1, args.part_size)
        tasks += [{**base[j], "part": part} for j, part in parts]
        owner = [j for j, _ in parts]
    tic = time.perf_counter()
    results = run_tasks(
        dfki.controller_job, tasks, ray_address=args.ray, max_workers=args.workers, progress="DFKI protocol"
    )
    wall = time.perf_counter() - tic
    for j, ((scene, name), res) in enumerate(zip(jobs, results)):
        source = gains[scene, name][1]
        name = name + (CATCH_SUFFIX if args.robust_catch else "") + (RATES_SUFFIX if args.rates_from_angles else "")
        c = res["criteria"]
        run_, plant = res["run"], gym.make(SCENES[scene]).unwrapped
        use = (
            dfki.torque_use(run_["T"], run_["v"], run_["u"], plant.driven, c["swingup_time"])
            if "swingup_time" in c
            else {}
        )
        row = {"scene": scene, "controller": name, "gains": source, **c, **use, "wall_s": res["wall_s"]}
        if args.robust_catch:
            row["catch_gains"] = json.dumps(base[j]["catch_gains"], sort_keys=True)
        plot_run(
            run_,
            plant.model.params,
            f"{scene}: {name}",
            args.out / f"run_{scene}_{slug(name)}.png",
        )
        if args.robustness:
            mine = [(t["part"], r) for t, r, o in zip(tasks[len(jobs) :], results[len(jobs) :], owner) if o == j]
            sweeps[(scene, name)] = dfki.assemble_sweep(metas[j], [p for p, _ in mine], [r["success"] for _, r in mine])
            row.update({f"robust {a}": sweeps[(scene, name)][a]["fraction"] for a in dfki.AXES})
            row["robustness score"] = sweeps[(scene, name)]["score"]["value"]
            row["robustness core_s"] = sum(r["wall_s"] for _, r in mine)  # its parts' time, each on one worker
        rows.append(row)
        print(f"{scene}, {name}: success {c['success']:.0f}, score {c['score']:.3f}"
              + (f", robustness {row['robustness score']:.3f}" if args.robustness else ""))  # fmt: skip
    print(f"wall time {wall:.1f} s ({len(tasks)} tasks)")
    with open(args.out / "dfki.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    command = command_line("dfki.py")
    record = {"command": command, "rows": rows, "sweeps": {f"{s} | {n}": to_json(r) for (s, n), r in sweeps.items()},
              "protocol": {s: SCENES[s] for s in scenes}, "values_per_axis": args.values, "seed": args.seed, "wall_s": wall}  # fmt: skip
    (args.out / "dfki.json").write_text(json.dumps(record, indent=2, default=float))
    for scene in scenes:
        if any(k[0] == scene for k in sweeps):
            plot_success({n: [r] for (s, n), r in sweeps.items() if s == scene}, dfki.AXES, f"{scene} (DFKI robustness v2 axes): success",
                         args.out / f"robustness_{scene}.png")  # fmt: skip
    curves = {s: training_curves(agent_folders(specs[s])) for s in scenes}
    if any(curves.values()):
        plot_agent_curves(curves, args.out / "learning_curves.png")
    (args.out / "report.md").write_text(report(rows, args) + curves_section(curves))
    print(f"written {args.out}")
    return record


def agent_folders(specs: dict[str, str]) -> dict[str, list[str]]:
    """The agents among a scene's policies (:func:`policies`) by algorithm, their training seeds' folders:
    ``{"SAC (v2 reward)": [".../seed0", ...]}`` (the ``+ LQR`` pairings left out: the same agents)."""
    from mbs_envs.studies.comparison import HAND_OVER

    out: dict[str, list[str]] = {}
    for name, spec in specs.items():
        if name in MODEL_BASED or spec.startswith(HAND_OVER):
            continue
        out.setdefault(catch_group(name), []).append(spec)
    return out


def plot_agent_curves(curves: dict[str, dict], path: pathlib.Path) -> None:
    """Per robot: the validation success of each algorithm's agents (mean, band = range over training seeds) against
    control steps and training wall time."""
    scenes = [s for s in curves if curves[s]]
    plt = pyplot()
    fig, axes = plt.subplots(len(scenes), 2, figsize=(12, 3.4 * len(scenes)), squeeze=False)
    for row, scene in zip(axes, scenes):
        for name, c in curves[scene].items():
            for ax, key in zip(row, ("timesteps", "train_wall_s")):
                draw(ax, name, c["runs"], "success", key)
        for ax in row:
            ax.set_ylim(-0.05, 1.05)
            ax.set_ylabel("validation success")
            ax.legend(fontsize=7)
            ax.set_title(f"{scene} (protocol plant)", loc="left", fontsize=10, fontweight="bold")
        row[0].set_xlabel("control steps (2 ms)")
        row[1].set_xlabel("training wall time [s] (one thread)")
    fig.suptitle("Agents trained on the protocol plant: validation success (mean, band = range over training seeds)",
                 fontsize=10)  # fmt: skip
    save(fig, path)


def curves_section(curves: dict[str, dict]) -> str:
    """The report's section on the agents' training: per algorithm and seed, its budget, wall time and command."""
    if not any(curves.values()):
        return ""
    out = ["## Training of the agents", "",
           "Each agent trained on the protocol's plant (its training id: the protocol's setup, with the reward of the "
           "task version it names), validated on the protocol's start every evaluation with the task's own success "
           "rule (both joints within 0.1 rad of upright for the last 2 s; the protocol asks for the tip's height only), "
           "the evaluation with the highest validation return shipped, or, where the table says so, the checkpoint "
           "with the best protocol score (`scripts/dfki_select.py`; then it decides every `K` control steps as the "
           "table gives). A continued agent's row counts its whole chain of runs, and lists their commands in "
           "order. ![learning curves](learning_curves.png)", "",
           "| robot | agent | seed | control steps | decisions (action repeat) | training wall [s] | kept at | commands |",
           "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for scene, by_name in curves.items():
        for name, c in by_name.items():
            for r in c["runs"]:
                k = r["action_repeat"]
                out.append(f"| {scene} | {name} | {r['seed']} | {r['steps']:,}{last_run(r)} | {r['steps'] // k:,} ({k}) | "
                           f"{r['wall']:.0f}{last_run(r)} | {kept_at(r)} | {commands_cell(r)} |")  # fmt: skip
    return "\n".join(out) + "\n"


def last_run(r: dict) -> str:
    """A note for a continued agent shipped without its chain's log (its row then counts its last run only)."""
    return " (its last run)" if r.get("init") and r["runs"] == 1 else ""


def kept_at(r: dict) -> str:
    """Which agent of a run was shipped: the last, the evaluation kept for its validation return (control steps of
    its run), or the checkpoint kept for its protocol score (with the decision interval it runs with)."""
    kept = r.get("kept")
    if not kept:
        return "last"
    if "checkpoint" in kept:
        every = r.get("evaluated_action_repeat") or r["action_repeat"]
        return f"checkpoint {kept['checkpoint']:,} of its last run, best protocol score; deciding every {every}"
    return f"{kept['timesteps']:,.0f}"


def commands_cell(r: dict) -> str:
    """The commands of an agent's chain of runs, in order."""
    return "; then ".join(f"`{c}`" if c else "(not recorded)" for c in r["commands"])


def sweep_parts_of(jobs: list[tuple[str, str]], values: int, seed: int, workers: int, part_size: int | None = None
                   ) -> tuple[list[tuple[int, dfki.SweepPart]], dict[int, dict]]:  # fmt: skip
    """The parts of every job's sweep, as ``(job index, part)``, and each job's axis descriptions.

    A model-based controller's sweep is cut in parts of ``part_size`` members (default: about 4 parts per worker over
    all of them, at most :data:`PART_MEMBERS` members: a control step's Python is paid once per part; the planner's
    acrobot sweep took 194 core-seconds in parts of 16 against 170 in parts of 32, its protocol episode included); an agent's stays one batch per
    axis: its network's outputs move in the last bits with the batch size (:func:`mbs_envs.studies.robustness.run`),
    so only whole batches give the committed runs' episodes. The parts go out largest first (stably: an axis' parts
    stay in their order), so that the pool's last tasks are small ones."""
    model_based = {j for j, (_, name) in enumerate(jobs) if name in MODEL_BASED}
    whole, metas = {}, {}
    for j, (scene, _) in enumerate(jobs):
        whole[j], metas[j] = dfki.sweep_parts(SCENES[scene], values, seed)
    members = sum(part.size for j in model_based for part in whole[j])
    default = min(PART_MEMBERS, max(1, -(-members // (4 * workers))))
    size = check.integer(part_size, "part_size", 1, 10**9) if part_size is not None else default
    out = [(j, piece) for j in whole for part in whole[j] for piece in (part.cut(size) if j in model_based else [part])]
    return sorted(out, key=lambda jp: -(jp[1].members.stop - jp[1].members.start)), metas


def policies(scene: str, agents: pathlib.Path | None) -> dict[str, str]:
    """Name -> spec of every policy run on the protocol: the model-based swing-up controllers, then each agent trained
    on the protocol plant (``<agents>/<scene>DFKI-v<k>/<algo>/seed<j>/agent.zip``, one row per training seed; an agent of a
    later task version, ``DFKI-v2``'s reward, named with it) alone and with
    the protocol plant's upright LQR catching (``"<ALGO> + LQR seed<k>"``, :mod:`mbs_envs.studies.handover`)."""
    from mbs_envs.studies.comparison import AGENT_GROUPS, HAND_OVER, version_tag

    out = dict(MODEL_BASED)
    if agents is None:
        return out
    for folder in sorted(pathlib.Path(agents).glob(f"{scene}DFKI-v*/*/seed*/agent.zip")):
        algo, seed, version = folder.parent.parent.name, folder.parent.name, folder.parents[2].name.rpartition("-")[2]
        name = AGENT_GROUPS.get(algo, (algo.upper(),))[0] + ("" if version == "v1" else version_tag(version))
        out[f"{name} {seed}"] = str(folder.parent)
        out[f"{name} + LQR {seed}"] = HAND_OVER + str(folder.parent)
    return out


def protocol_gains(scene: str, name: str) -> tuple[dict | None, str]:
    """The gains this controller runs with on the protocol and where they come from: those tuned on the protocol id
    where ``controllers/tuned.json`` has them (``--tune --write``; for a controller without an entry of its own, that
    of the controller whose laws it shares; ``"protocol"``), else those the project's tuning picked on our own scene
    of the same task (``mbs_envs/<scene>-v1``; ``"own scene"``). ``(None, "")`` for a policy without tuned gains: an
    agent, or a protocol controller (:data:`PROTOCOL_CONTROLLERS`, whose report states its own settings)."""
    from mbs_envs.controllers.tuned import stored_entry, tuned_gains
    from mbs_envs.studies.evaluation import controller_class

    if name not in SWING_UP_CONTROLLERS:
        return None, ""
    tuned_name = getattr(controller_class(SWING_UP_CONTROLLERS[name]), "tuned_name", None)
    if tuned_name is None:
        return None, ""
    entry = stored_entry(SCENES[scene], tuned_name)
    if entry is not None:
        return entry, "protocol"
    return tuned_gains(gym.make(f"mbs_envs/{scene}-v1"), tuned_name), "own scene"


def catch_group(name: str) -> str:
    """The name a policy's robust catch is tuned and stored under: an agent's seeds share one (``"PPO + LQR seed1"`` ->
    ``"PPO + LQR"``)."""
    head, _, tail = name.rpartition(" ")
    return head if head and tail.startswith("seed") and tail[4:].isdigit() else name


def robust_catch_entry(scene: str, name: str) -> dict | None:
    """The catch tuned for robustness (``{"lqr_r", "catch"}``, and ``release`` after the second stage) stored for this
    policy on the protocol id, or None."""
    from mbs_envs.controllers.tuned import stored_entry

    return stored_entry(SCENES[scene], catch_group(name) + CATCH_SUFFIX)


def catching_policies(scene: str, agents: pathlib.Path) -> dict[str, str]:
    """Name -> spec of the policies with a catching LQR on the protocol: the energy controllers (not the planner, whose
    time-varying LQR and replanning are its own) and every agent with the LQR catching."""
    from mbs_envs.studies.comparison import HAND_OVER

    return {n: s for n, s in policies(scene, agents).items()
            if n in ("swing-up + LQR", "adaptive swing-up + LQR") or s.startswith(HAND_OVER)}  # fmt: skip


def tune_robust_catch(args: argparse.Namespace) -> dict:
    """``--tune-robust-catch``: :func:`mbs_envs.studies.dfki_tuning.robust_catch` per scene; ``robust_catch.json`` and
    ``robust_catch.csv`` to ``--out``, and with ``--write`` each group's pick into ``controllers/tuned.json`` as
    ``"<group> (robust catch)"`` under the protocol id."""
    from mbs_envs.studies import dfki_tuning

    args.out.mkdir(parents=True, exist_ok=True)
    command = command_line("dfki.py")
    record: dict = {"procedure": dfki_tuning.robust_catch.__doc__, "command": command, "tuning_set": dict(dfki_tuning.ROBUST_SET),
                    "rates_from_angles": args.rates_from_angles, "gains": {}, "scenes": {}}  # fmt: skip
    rows = []
    for scene in args.scene or sorted(SCENES):
        specs = catching_policies(scene, args.agents)
        if args.controller:
            specs = {n: s for n, s in specs.items() if n in args.controller or catch_group(n) in args.controller}
        pols = {n: {"spec": s, "gains": protocol_gains(scene, n)[0]} for n, s in specs.items()}
        groups: dict[str, list[str]] = {}
        for n in pols:
            groups.setdefault(catch_group(n), []).append(n)
        progress = f"{scene}: catch tuned for robustness"
        if args.release_stage:
            res = release_stage(scene, pols, groups, args, progress)
        else:
            res = dfki_tuning.robust_catch(
                SCENES[scene],
                pols,
                groups,
                rates_from_angles=args.rates_from_angles,
                workers=args.workers,
                progress=progress,
            )
        record["gains"][SCENES[scene]] = {g + CATCH_SUFFIX: pick for g, pick in res["picks"].items()}
        picked = {g: [r for r in res["rows"] if r["policy"] in groups[g] and all(r.get(k) == v for k, v in pick.items())]
                  for g, pick in res["picks"].items()}  # fmt: skip
        record.setdefault("scores", {})[SCENES[scene]] = {
            g + CATCH_SUFFIX: {"tuning_set_robustness": {r["policy"]: r["score"] for r in picked[g]},
                               "candidates": sum(r["policy"] == groups[g][0] for r in res["rows"]), "tuning_set": dict(dfki_tuning.ROBUST_SET),
                               "stage": "release" if args.release_stage else "lqr_r and catch",
                               "rates_from_angles": args.rates_from_angles, "wall_s": res["wall_s"], "command": command}
            for g in res["picks"]}  # fmt: skip
        record["scenes"][scene] = {"groups": groups, "picks": res["picks"], "wall_s": res["wall_s"]}
        rows += [{"scene": scene, **r} for r in res["rows"]]
        for g, pick in res["picks"].items():
            print(
                f"{scene}, {g}: {pick}, tuning-set robustness "
                + ", ".join(f"{r['score']:.3f}" for r in picked[g])
                + f" ({res['wall_s']:.0f} s)"
            )
    record["rows"] = rows
    write_tuning(args.out, "robust_catch", rows, record, args.write)
    return record


def release_stage(
    scene: str, pols: dict, groups: dict[str, list[str]], args: argparse.Namespace, progress: str
) -> dict:
    """``--release-stage``: per group with a stored robust catch, its ``lqr_r`` and ``catch`` with each release factor
    (``--release-values`` or :data:`~mbs_envs.studies.dfki_tuning.ROBUST_RELEASE`), one tuning run per group; the
    results merged as :func:`mbs_envs.studies.dfki_tuning.robust_catch` returns them. Groups without one are skipped."""
    from mbs_envs.studies import dfki_tuning

    values = tuple(args.release_values) if args.release_values else dfki_tuning.ROBUST_RELEASE
    stored = {g: robust_catch_entry(scene, g) for g in groups}
    missing = sorted(g for g, e in stored.items() if e is None)
    if missing:
        print(f"--release-stage: no catch tuned for robustness stored for {', '.join(missing)} ({scene}): not tuned")
    res: dict = {"rows": [], "picks": {}, "wall_s": 0.0}
    for g in (g for g in groups if stored[g] is not None):
        one = dfki_tuning.robust_catch(SCENES[scene], {n: pols[n] for n in groups[g]}, {g: groups[g]},
                                       candidates=dfki_tuning.release_grid(stored[g], values), rates_from_angles=args.rates_from_angles,
                                       workers=args.workers, progress=f"{progress}: {g}, release")  # fmt: skip
        res["rows"] += one["rows"]
        res["picks"].update(one["picks"])
        res["wall_s"] += one["wall_s"]
    return res


def write_tuning(out: pathlib.Path, stem: str, rows: list[dict], record: dict, store: bool) -> None:
    """``<stem>.csv`` (one row per candidate; a column missing from a row left empty) and ``<stem>.json`` to ``out``;
    with ``store`` the record's ``gains`` and ``scores`` into ``controllers/tuned.json`` (other entries kept)."""
    from mbs_envs.controllers import tuned

    with open(out / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(dict.fromkeys(k for r in rows for k in r)))
        w.writeheader()
        w.writerows(rows)
    (out / f"{stem}.json").write_text(json.dumps(record, indent=2))
    if store:
        stored = json.loads(tuned.PATH.read_text())
        for key in ("gains", "scores"):
            for env_id, entries in record[key].items():
                stored.setdefault(key, {}).setdefault(env_id, {}).update(entries)
        tuned.PATH.write_text(json.dumps(stored, indent=2) + "\n")
        tuned.clear_cache()
    print(f"written {out}")


def tune(args: argparse.Namespace) -> dict:
    """``--tune``: :func:`mbs_envs.studies.dfki_tuning.tune` per scene; ``tuning.json`` (and ``tuning.csv``) to ``--out``,
    and with ``--write`` the picks into ``controllers/tuned.json`` under the protocol ids (other entries kept)."""
    from mbs_envs.studies import dfki_tuning, tuning

    args.out.mkdir(parents=True, exist_ok=True)
    command = command_line("dfki.py")
    record: dict = {"procedure": dfki_tuning.__doc__, "command": command, "gains": {}, "scores": {}}
    rows = []
    scenes = args.scene or sorted(SCENES)
    results = run_tasks(dfki_tuning.tune_job, [{"env_id": SCENES[s]} for s in scenes], ray_address=args.ray, max_workers=args.workers,
                        progress="scenes tuned on the protocol")  # fmt: skip
    for scene, result in zip(scenes, results):
        env_id = SCENES[scene]
        for name, res in result.items():
            chosen = [r for r in res["rows"] if r["entry"] == res["best"]][-1]  # its last stage's row
            record["gains"].setdefault(env_id, {})[name] = res["best"]
            record["scores"].setdefault(env_id, {})[name] = {**{k: v for k, v in chosen.items() if k != "entry"}, "candidates": len(res["rows"]),
                                                             "at_grid_edge": tuning.at_grid_edge(res["best"], [r["entry"] for r in res["rows"]]), "wall_s": res["wall_s"],
                                                             "command": command}  # fmt: skip
            rows += [{"scene": scene, "controller": name, **r, "entry": json.dumps(r["entry"])} for r in res["rows"]]
            print(f"{scene}, {name}: {res['best']} ({len(res['rows'])} candidates, {res['wall_s']:.0f} s): "
                  + ", ".join(f"{k} {v:.3g}" for k, v in chosen.items() if k != "entry"))  # fmt: skip
    write_tuning(args.out, "tuning", rows, record, args.write)  # a stage's own columns empty in the others' rows
    return record


def slug(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name).strip("_")


def to_json(res: dict) -> dict:
    return {
        a: {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()}
        for a, d in res.items()
    }


def plot_run(run_: dict, p, title: str, path: pathlib.Path) -> None:
    """Angles (their convention: hanging 0), velocities, torque, and the end effector's height against the threshold."""
    plt = pyplot()
    fig, ax = plt.subplots(4, 1, figsize=(7, 7), sharex=True)
    T, q, v, u = run_["T"], run_["q"], run_["v"], run_["u"]
    ax[0].plot(T, q + np.array([np.pi / 2, 0.0]))
    ax[0].set(ylabel="q (hanging 0) [rad]")
    ax[1].plot(T, v)
    ax[1].set(ylabel="v [rad/s]")
    ax[2].plot(T, u)
    ax[2].set(ylabel="u [N m]")
    ax[3].plot(T, dfki.end_effector_height(q, p.l1, p.l2))
    ax[3].axhline(dfki.HEIGHT * (p.l1 + p.l2), color="k", ls="--", lw=0.8)
    ax[3].set(ylabel="tip height [m]", xlabel="t [s]")
    ax[0].set_title(title)
    save(fig, path)


def gains_sentence(rows: list[dict]) -> str:
    """Which controllers ran with gains tuned on the protocol and which with those of our own scene."""
    by = {
        src: sorted({f"{r['controller']} ({r['scene']})" for r in rows if r.get("gains") == src})
        for src in ("protocol", "own scene")
    }
    parts = []
    if by["protocol"]:
        parts.append(
            "tuned on the protocol itself (`scripts/dfki.py --tune`, `mbs_envs/studies/dfki_tuning.py`; the identified planner's "
            "entry picked there between its own scene's and the adaptive controller's pick) for "
            + ", ".join(by["protocol"])
        )
    if by["own scene"]:
        parts.append(
            "those the project's tuning picked on our own scene of the same task (`mbs_envs/<scene>-v1`, `controllers/tuned.json`; "
            "none tuned on this plant) for " + ", ".join(by["own scene"])
        )
    from .evaluation import controller_class

    notes: dict[str, list[str]] = {}  # a protocol controller's own account of its settings -> who has it
    for r in rows:
        if r["controller"] in PROTOCOL_CONTROLLERS:
            note = controller_class(PROTOCOL_CONTROLLERS[r["controller"]]).settings_note
            notes.setdefault(note, []).append(f"{r['controller']} ({r['scene']})")
    for note, who in notes.items():
        parts.append(note + " for " + ", ".join(sorted(set(who))))
    return "; ".join(parts) + "." if parts else "none (agents only)."


def report(rows: list[dict], args: argparse.Namespace) -> str:
    out = ["# The DFKI double-pendulum benchmark: our controllers beside the leaderboards", "",
           "Protocol: `mbs_envs/AcrobotDFKI-v1` / `mbs_envs/PendubotDFKI-v1` (design C.1, model 1.0 as the leaderboard "
           "simulates it: 6 N m on the driven joint, RK4 at 2 ms, 10 s from hanging at rest); success and score "
           "(simulation v2) as `mbs_envs/studies/dfki.py` computes them. Our controllers' gains: "
           + gains_sentence(rows), ""]  # fmt: skip
    if args.rates_from_angles:
        passed = sorted(
            {int(round(r["robust velocity noise"] * args.values)) for r in rows if "robust velocity noise" in r}
        )
        out += ["**Rates from angles** (`--rates-from-angles`): every policy here sees the joint rates differenced from the "
                "observed angles (the second-order backward difference, `controllers.estimator.RatesFromAngles`) instead "
                "of the observed rates. The velocity-noise axis perturbs only the observed rates, so it reaches these "
                "policies only through the first step's (the difference needs two angles): each of its episodes differs from "
                "the noise-free one by that step alone, so the axis mostly repeats the nominal episode"
                + (f" (in this run the policies passed {', '.join(map(str, passed))} of its {args.values} episodes)" if passed else "")
                + " and scores the estimator rather than the controller. The published entries see the noisy rates (or "
                "their own filters of them).", ""]  # fmt: skip
    if args.robust_catch:
        from mbs_envs.studies.dfki_tuning import ROBUST_SET

        used = "; ".join(f"{r['controller']} ({r['scene']}): {r['catch_gains']}" for r in rows)
        out += ["**Robust catch** (`--robust-catch`): each policy's catching LQR -- its input weight `lqr_r` and catch level "
                "`catch` of `x^T S x` -- is the one picked for robustness (`scripts/dfki.py --tune-robust-catch`, "
                "`mbs_envs.studies.dfki_tuning.robust_catch`): the best mean robustness score, among the candidates under which "
                "every member swings up in the nominal episode, on a tuning set of the six axes whose values are drawn "
                f"uniformly over the benchmark's ranges ({ROBUST_SET['n']} per axis, noise and pulses from seed {ROBUST_SET['seed']}), never on the benchmark's grid "
                "scored here; an agent's training seeds share one pick. Used: " + used + ".", ""]  # fmt: skip
    for scene in dict.fromkeys(r["scene"] for r in rows):
        out += [f"## {scene}: simulation v2", "", "| controller | success | swing-up time [s] | energy [J] | torque cost | smoothness [N m] | velocity cost | score |",
                "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in rows:
            if r["scene"] == scene:
                vals = " | ".join(f"{r[k]:.3g}" if k in r else "" for k in CRITERIA)
                out.append(f"| **ours: {r['controller']}** | {r['success']:.0f}/1 | {vals} | **{r['score']:.3f}** |")
        pub = dfki.PUBLISHED_SIMULATION_V2.get(scene)
        if pub:
            for name, v in pub["rows"].items():
                out.append(f"| {name} (published) | 1/1 | " + " | ".join(f"{x:g}" for x in v[:5]) + f" | {v[5]:.3f} |")
            out += ["", f"Published rows: {pub['url']}"]
        else:
            out += ["", "(No published simulation-v2 table for this scene was at hand.)"]
        out.append("")
        if any("torque_use" in r for r in rows if r["scene"] == scene):
            out += [f"## {scene}: how much of the swing-up's torque does work", "",
                    "Over the swing-up the torque does the work `W = sum |u_d v_d| dt` at the driven joint; at the same "
                    "rates no torque doing that work costs less than `W^2 / sum v_d^2 dt` (Cauchy-Schwarz), reached only "
                    "when the torque follows the joint's rate (`mbs_envs.studies.dfki.torque_use`). The share is that "
                    "least cost over the swing-up's own: torque held against a still joint costs and does no work.", "",
                    "| controller | swing-up time [s] | work [J] | torque cost of the swing-up | least for its work | share |",
                    "|---|---|---|---|---|---|"]  # fmt: skip
            for r in rows:
                if r["scene"] == scene and "torque_use" in r:
                    out.append(f"| {r['controller']} | {r['swingup_time']:.3g} | {r['work']:.3g} | {r['swingup_tau_cost']:.3g} "
                               f"| {r['least_tau_cost']:.3g} | {r['torque_use']:.2f} |")  # fmt: skip
            out.append("")
        if args.robustness:
            out += [f"## {scene}: robustness v2 (success [%] per axis; score = mean of the six)", "",
                    "| controller | " + " | ".join(dfki.AXES) + " | score |", "|---" * (len(dfki.AXES) + 2) + "|"]  # fmt: skip
            for r in rows:
                if r["scene"] == scene:
                    out.append(f"| **ours: {r['controller']}** | " + " | ".join(f"{100 * r['robust ' + a]:.1f}" for a in dfki.AXES)
                               + f" | **{r['robustness score']:.3f}** |")  # fmt: skip
            pub = dfki.PUBLISHED_ROBUSTNESS_V2.get(scene)
            if pub:
                for name, v in pub["rows"].items():
                    out.append(f"| {name} (published) | " + " | ".join(f"{x:g}" for x in v[:6]) + f" | {v[6]:.3f} |")
                out += ["", f"Published rows: {pub['url']}"]
            out += ["", f"Our sweep: {args.values} values per axis (theirs 21); the model axis varies m1 r1, I1, m2 r2, m2, I2 "
                    "x[0.75, 1.25] in their convention and the damping b1, b2 over [0, 0.1] (theirs [-0.1, 0.1]), leaves out "
                    "the motor inertia and Coulomb friction (not in our plant as they model them) and the variations with no "
                    "rigid link (an inertia about the joint below m r^2); perturbations enter as impulses per step "
                    f"(`mbs_envs/studies/robustness.py`). ![robustness](robustness_{scene}.png)", ""]  # fmt: skip
    return "\n".join(out) + "\n"


def check_args(args: argparse.Namespace) -> None:
    """Refuse combinations of options that do not go together (SystemExit, before anything runs)."""
    if args.write and not (args.tune or args.tune_robust_catch):
        raise SystemExit("dfki.py: --write stores the picks of --tune or --tune-robust-catch; give one of them")
    if args.release_stage and not args.tune_robust_catch:
        raise SystemExit("dfki.py: --release-stage is a stage of --tune-robust-catch; give both")
    if args.release_values and not args.release_stage:
        raise SystemExit("dfki.py: --release-values are the factors of --release-stage; give it")
    if args.tune and args.tune_robust_catch:
        raise SystemExit("dfki.py: --tune and --tune-robust-catch are separate runs; give one")
