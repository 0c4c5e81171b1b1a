"""Results at a glance: small Markdown tables read off the committed reports.

The README and the docs' benchmarks page show these tables; ``scripts/readme.py`` writes them between
``<!-- glance:NAME -->`` and ``<!-- /glance:NAME -->`` markers, and the tests check that the committed README
equals what the committed reports give. Nothing here is typed by hand: each figure is a field of a report.

Reports read (paths relative to the repository):

- ``docs/figures/compare/summary.json``: the main job (``scripts/compare.py``), tracking and swing-up scenes;
- ``docs/figures/dfki/performance/dfki.json``: the DFKI protocol, simulation v2 (``scripts/dfki.py``);
- ``docs/figures/dfki/robustness/<Robot>/dfki.json``: its robustness v2 sweep;
- ``docs/figures/dfki/v3/v3.json``: the global-policy protocol, simulation v3 (``scripts/dfki_v3.py``);
- ``docs/figures/dfki/agents/dfki.json``: the agents trained on the protocol's plant, with their robustness v2.
"""

from __future__ import annotations

import json
import pathlib
import re
from collections.abc import Callable, Mapping
from typing import Any

from .dfki import PUBLISHED_PURE_RL, PUBLISHED_ROBUSTNESS_V2, PUBLISHED_SIMULATION_V2
from .dfki_v3 import PUBLISHED_V3

#: the reports, relative to the repository root
COMPARE = "docs/figures/compare/summary.json"
DFKI_PERFORMANCE = "docs/figures/dfki/performance/dfki.json"
DFKI_ROBUSTNESS = "docs/figures/dfki/robustness/{robot}/dfki.json"
DFKI_V3 = "docs/figures/dfki/v3/v3.json"
DFKI_AGENTS = "docs/figures/dfki/agents/dfki.json"

#: the success a policy needs at the nominal plant to count as "best" on its side (as the report's rule)
BEST_SUCCESS = 0.95


def _g(x: float) -> str:
    return f"{x:.3g}"


def _pct(c: Mapping[str, Any], key: str = "success") -> str:
    lo, hi = c.get(f"{key}_lo"), c.get(f"{key}_hi")
    value = f"{100 * c[key]:.0f} %"
    return value if lo is None or lo == hi else f"{value} [{100 * lo:.0f}, {100 * hi:.0f}]"


def best(cells: Mapping[str, Mapping[str, Any]], kind: str, key: Callable[[Mapping[str, Any]], Any]) -> str | None:
    """The name of the policy of ``kind`` that ``key`` ranks first (smallest), or None if there is none."""
    names = [n for n, c in cells.items() if c["kind"] == kind]
    return min(names, key=lambda n: key(cells[n])) if names else None


def tracking_table(summary: Mapping[str, Any]) -> str:
    """Per tracking scene, the best model-based controller and the best RL agent at the nominal plant.

    Best: among the policies with at least :data:`BEST_SUCCESS` success, the smallest settled RMS error (the
    report's rule; otherwise the highest success).
    """

    def rank(c):
        return (c["success"] < BEST_SUCCESS, -c["success"] if c["success"] < BEST_SUCCESS else c["rms_error_settled"])

    rows = ["| scene | best model-based | settled error [rad] | success | best RL | settled error [rad] | success |",
            "|---|---|---|---|---|---|---|"]  # fmt: skip
    for scene, conditions in summary["summary"].items():
        cells = conditions["nominal"]
        if "time_to_swing_up" in next(iter(cells.values())):
            continue
        cols = []
        for kind in ("model-based", "RL"):
            name = best(cells, kind, rank)
            c = cells[name]
            err = f"{_g(c['rms_error_settled'])} [{_g(c['rms_error_settled_lo'])}, {_g(c['rms_error_settled_hi'])}]"
            cols += [name, err, _pct(c)]
        rows.append(f"| {scene} | " + " | ".join(cols) + " |")
    return "\n".join(rows)


def swingup_table(summary: Mapping[str, Any]) -> str:
    """Per swing-up scene, the success within 0.1 rad of the best policy of each side at the nominal plant.

    Best: the highest success, then the shortest time to swing up.
    """

    def rank(c):
        return (-c["success"], c.get("time_to_swing_up", float("inf")))

    sides = (("model-based", "best model-based"), ("RL", "best pure RL"), ("model-based + RL", "best RL + LQR"))
    rows = ["| scene | " + " | ".join(f"{label} | success" for _, label in sides) + " |",
            "|---|" + "---|---|" * len(sides)]  # fmt: skip
    for scene, conditions in summary["summary"].items():
        cells = conditions["nominal"]
        if "time_to_swing_up" not in next(iter(cells.values())):
            continue
        cols = []
        for kind, _ in sides:
            name = best(cells, kind, rank)
            cols += [name, _pct(cells[name])] if name else ["-", "-"]
        rows.append(f"| {scene} | " + " | ".join(cols) + " |")
    return "\n".join(rows)


def dfki_table(performance: Mapping[str, Any], robustness: Mapping[str, Mapping[str, Any]]) -> str:
    """Per robot, our best simulation-v2 score and our best robustness-v2 score beside the best published ones.

    ``robustness``: robot -> its robustness report (``dfki.json`` with ``sweeps``).
    """
    rows = ["| robot | ours, simulation v2 | score | best published | score | ours, robustness v2 | score "
            "| best published | score |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    robots = list(dict.fromkeys(r["scene"] for r in performance["rows"]))
    for robot in robots:
        ours = max((r for r in performance["rows"] if r["scene"] == robot), key=lambda r: r["score"])
        pub = PUBLISHED_SIMULATION_V2.get(robot, {}).get("rows", {})
        pub_best = max(pub, key=lambda n: pub[n][-1]) if pub else None
        sweeps = robustness.get(robot, {}).get("sweeps", {})
        scores = {k.split(" | ", 1)[1]: v["score"]["value"] for k, v in sweeps.items()}
        rob = max(scores, key=scores.get) if scores else None
        rpub = PUBLISHED_ROBUSTNESS_V2.get(robot, {}).get("rows", {})
        rpub_best = max(rpub, key=lambda n: rpub[n][-1]) if rpub else None
        rows.append(" | ".join([f"| {robot}", ours["controller"], f"{ours['score']:.3f}",
                                pub_best or "-", f"{pub[pub_best][-1]:.3f}" if pub_best else "-",
                                rob or "-", f"{scores[rob]:.3f}" if rob else "-",
                                rpub_best or "-", f"{rpub[rpub_best][-1]:.3f}" if rpub_best else "-"]) + " |")  # fmt: skip
    return "\n".join(rows)


def dfki_rl_table(agents: Mapping[str, Any]) -> str:
    """Per robot, our best pure RL agent on the DFKI protocol (no LQR catching: an agents report's rows without
    ``" + LQR"``) by simulation-v2 score, with its robustness-v2 score, beside the best published pure RL entries
    (:data:`~mbs_envs.studies.dfki.PUBLISHED_PURE_RL`) on each leaderboard."""
    rows = ["| robot | ours, pure RL | simulation v2 | robustness v2 | best published pure RL, simulation v2 | score "
            "| best published pure RL, robustness v2 | score |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for robot in dict.fromkeys(r["scene"] for r in agents["rows"]):
        pure = [r for r in agents["rows"] if r["scene"] == robot and "+ LQR" not in r["controller"]]
        if not pure:
            continue
        ours = max(pure, key=lambda r: r["score"])
        rob = agents.get("sweeps", {}).get(f"{robot} | {ours['controller']}", {}).get("score", {}).get("value")
        cells = [f"| {robot}", ours["controller"], f"{ours['score']:.3f}", f"{rob:.3f}" if rob is not None else "-"]
        for table in (PUBLISHED_SIMULATION_V2, PUBLISHED_ROBUSTNESS_V2):
            pub = {n: v[-1] for n, v in table.get(robot, {}).get("rows", {}).items() if n in PUBLISHED_PURE_RL}
            name = max(pub, key=pub.get) if pub else None
            cells += [name or "-", f"{pub[name]:.3f}" if name else "-"]
        rows.append(" | ".join(cells) + " |")
    return "\n".join(rows)


def dfki_v3_table(v3: Mapping[str, Any]) -> str:
    """Per robot, our best simulation-v3 score (mean over its seeds, with their range) beside the best published one."""
    rows = ["| robot | ours, simulation v3 | uptime score | range over seeds | best published | uptime score |",
            "|---|---|---|---|---|---|"]  # fmt: skip
    for env_id in dict.fromkeys(r["env_id"] for r in v3["summary"]):
        ours = max((r for r in v3["summary"] if r["env_id"] == env_id), key=lambda r: r["score"])
        pub = PUBLISHED_V3.get(env_id, {})
        best = max(pub, key=pub.get) if pub else None
        robot = env_id.split("/")[-1].replace("DFKI-v1", "")
        rows.append(f"| {robot} | {ours['controller']} | {ours['score']:.3f} | {ours['min']:.3f} - {ours['max']:.3f} "
                    f"({len(ours['seeds'])} seeds) | {best or '-'} | {f'{pub[best]:.3f}' if best else '-'} |")  # fmt: skip
    return "\n".join(rows)


def tables(root: pathlib.Path) -> dict[str, str]:
    """Every glance table by marker name, read from the reports under the repository ``root``."""
    summary = json.loads((root / COMPARE).read_text())
    performance = json.loads((root / DFKI_PERFORMANCE).read_text())
    robustness = {}
    for robot in dict.fromkeys(r["scene"] for r in performance["rows"]):
        path = root / DFKI_ROBUSTNESS.format(robot=robot)
        if path.exists():
            robustness[robot] = json.loads(path.read_text())
    v3 = json.loads((root / DFKI_V3).read_text())
    agents = json.loads((root / DFKI_AGENTS).read_text())
    return {"tracking": tracking_table(summary), "swingup": swingup_table(summary),
            "dfki": dfki_table(performance, robustness), "dfki_rl": dfki_rl_table(agents),
            "dfki_v3": dfki_v3_table(v3)}  # fmt: skip


def fill(text: str, blocks: Mapping[str, str]) -> str:
    """``text`` with each ``<!-- glance:NAME -->...<!-- /glance:NAME -->`` block replaced by ``blocks[NAME]``.

    Raises
    ------
    ValueError
        Naming a block of ``blocks`` whose markers ``text`` lacks.
    """
    for name, body in blocks.items():
        pattern = re.compile(rf"(<!-- glance:{re.escape(name)} -->\n).*?(<!-- /glance:{re.escape(name)} -->)", re.S)
        if not pattern.search(text):
            raise ValueError(f"no markers for the block {name!r} (<!-- glance:{name} --> ... <!-- /glance:{name} -->)")
        text = pattern.sub(lambda m: m.group(1) + body.rstrip("\n") + "\n" + m.group(2), text)
    return text
