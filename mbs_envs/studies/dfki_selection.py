"""Choosing which checkpoint of a training run on the DFKI protocol's plant to ship, by the protocol's own score.

An agent trained on ``mbs_envs/AcrobotDFKI-v2`` or ``mbs_envs/PendubotDFKI-v2`` is judged by the leaderboard's
simulation-v2 score on the protocol (:mod:`mbs_envs.studies.dfki`), whose start is a single deterministic state:
there is no held-out start to choose on, and the leaderboard's entrants choose their agents on that episode. The
training reward only approximates the score (it pays for balancing straight, the score for the tip's height; the score
charges the torque's smoothness, the reward does not), so the checkpoint with the best validation return is not the
one with the best score. Each checkpoint of the run is run on the protocol:

- holding each decision for the training's action repeat ``K`` (as trained), and
- deciding at every control step (``K = 1``, as the protocol calls its controllers: a trained policy is a feedback law
  of the state, and querying it at the control rate removes the steps its held torque makes every ``K`` steps, which
  the smoothness criterion charges);

the best score over (checkpoint, decision interval) is shipped with that interval (``"evaluated_action_repeat"`` in its
``config.json``, which :func:`mbs_envs.studies.training.load_agent` honours) and the choice recorded (``"kept"``).
The robustness-v2 sweep (perturbed plants, noise, delays, ...) plays no part in the choice, so it measures the
shipped agent away from what it was chosen on.
"""

from __future__ import annotations

import json
import pathlib
from typing import Any, Iterable

from ..envs.presets import PROTOCOL_IDS, TRAINING_IDS
from .training import CHECKPOINT

#: the criteria of a row, in the report's order
COLUMNS = ("success", "swingup_time", "energy", "tau_cost", "tau_smoothness", "velocity_cost", "score")


def protocol_id(env_id: str) -> str:
    """The protocol id (``...DFKI-v1``) of a protocol or training id on the protocol's plant.

    Raises
    ------
    ValueError
        ``env_id`` is neither.
    """
    for (pid, *_), (tid, *_) in zip(PROTOCOL_IDS, TRAINING_IDS):
        if env_id in (pid, tid):
            return pid
    known = [i[0] for i in PROTOCOL_IDS + TRAINING_IDS]
    raise ValueError(f"env_id: {env_id!r} is not on the DFKI protocol's plant; known: {known}")


def checkpoints(run: pathlib.Path) -> list[tuple[int, pathlib.Path]]:
    """A run's checkpoints as ``(control steps, file)``, earliest first (control steps = decisions x action repeat).

    Raises
    ------
    ValueError
        ``run`` has no ``config.json`` or no checkpoint.
    """
    run = pathlib.Path(run)
    if not (run / "config.json").exists():
        raise ValueError(f"run: {str(run)!r} is not a folder written by train (no config.json)")
    repeat = int(json.loads((run / "config.json").read_text()).get("action_repeat", 1))
    found = []
    for path in (run / "checkpoints").glob("agent_*_steps.zip"):
        match = CHECKPOINT.fullmatch(path.name)
        if match:
            found.append((int(match.group(1)) * repeat, path))
    if not found:
        raise ValueError(f"run: {str(run)!r} has no checkpoints (train with --checkpoint-every)")
    return sorted(found)


def protocol_row(agent_file: pathlib.Path, algo: str, env_id: str, action_repeat: int) -> dict[str, float]:
    """The protocol's criteria and simulation-v2 score of the agent in ``agent_file`` deciding every ``action_repeat``
    control steps."""
    from .dfki import protocol_episode
    from .held import HeldPolicy
    from .training import ALGOS

    model = ALGOS[algo].load(agent_file, device="cpu")
    policy = HeldPolicy(model, action_repeat) if action_repeat > 1 else model
    _, row = protocol_episode(protocol_id(env_id), policy)
    return {k: float(row[k]) for k in COLUMNS}


def evaluate_run(run: pathlib.Path, action_repeats: Iterable[int] | None = None, progress: bool = False
                 ) -> list[dict[str, Any]]:  # fmt: skip
    """Every checkpoint of ``run`` on the protocol at each decision interval (default: the training's and 1):
    rows ``{"checkpoint": control steps, "action_repeat": K, **criteria}``."""
    record = json.loads((pathlib.Path(run) / "config.json").read_text())
    trained = int(record.get("action_repeat", 1))
    ks = sorted(set(action_repeats or (trained, 1)), reverse=True)
    if any(not isinstance(k, int) or k < 1 for k in ks):
        raise ValueError(f"action_repeats: positive integers expected, got {ks}")
    jobs = [(steps, path, k) for steps, path in checkpoints(run) for k in ks]
    if progress:
        from tqdm import tqdm

        jobs = tqdm(jobs, desc="checkpoints on the protocol")
    return [{"checkpoint": steps, "action_repeat": k, **protocol_row(path, record["algo"], record["env_id"], k)}
            for steps, path, k in jobs]  # fmt: skip


def best(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The row with the highest score (a failed episode scores 0); on a tie the earliest checkpoint, then the longer
    decision interval (the training's)."""
    if not rows:
        raise ValueError("rows: nothing to choose from")
    return max(rows, key=lambda r: (r["score"], -r["checkpoint"], r["action_repeat"]))


def plot(rows: list[dict[str, Any]], path: pathlib.Path, title: str) -> None:
    """Score against control steps, one line per decision interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for k in sorted({r["action_repeat"] for r in rows}, reverse=True):
        mine = [r for r in rows if r["action_repeat"] == k]
        ax.plot([r["checkpoint"] / 1e6 for r in mine], [r["score"] for r in mine], "o-", ms=3,
                label=f"deciding every {k} control step{'s' if k > 1 else ''}")  # fmt: skip
    ax.set_xlabel("control steps of this run [millions]")
    ax.set_ylabel("simulation v2 score")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
