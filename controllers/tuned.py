"""The default gains of the model-based controllers: the tuned ones.

``controllers/tuned.json`` is written by ``scripts/tune.py`` (the procedure is
:mod:`mbs_envs.studies.tuning`: a grid over each controller's closed-loop bandwidth or
weights, scored on tuning seeds only, at the nominal plant and +-20 % mass
and length mismatch). Each entry is keyed by env id and controller name:

- joint controllers: ``{"omega": w, "zeta": z}``, a bandwidth [rad/s] and a
  damping ratio. Computed torque takes ``kp = w^2``, ``kd = 2 z w``
  [1/s^2, 1/s]; PD and PD + gravity ``kp = J w^2``, ``kd = 2 J z w`` with the
  env's ``joint_inertia`` ``J`` [kg m^2], so the numbers carry over to other
  parameters and chain lengths;
- ``LQR`` (disk): ``Q`` (5 diagonal weights), ``R`` (2, on the normalized
  input), ``q_integral``;
- ``PD steering`` (disk): ``k_dlean, k_lean, k_h, k_r, k_w``;
- ``swing-up + LQR`` (Acrobot, Pendubot): ``k_q, k_v, k_E, catch`` and optionally ``lqr_r``
  (the LQR's input weight, 1 if absent);
- ``adaptive swing-up + LQR`` (Acrobot, Pendubot): as ``swing-up + LQR``; without an entry of its
  own it takes the ``swing-up + LQR`` entry (:data:`SAME_LAWS`);
- ``RL + LQR`` (Acrobot, Pendubot): ``catch, release``, where an RL agent's swing-up hands over to
  the LQR (written by ``scripts/tune_handover.py``; :mod:`mbs_envs.studies.handover`).

The DFKI protocol ids (``mbs_envs/AcrobotDFKI-v1``, ``mbs_envs/PendubotDFKI-v1``) carry the energy controllers'
entries tuned on the protocol itself (``scripts/dfki.py --tune --write``; :mod:`mbs_envs.studies.dfki_tuning`), and
``"<policy> (robust catch)"`` entries ``{"lqr_r", "catch", "release"}``: a catching LQR's input weight, level and
hand-back factor picked for the benchmark's robustness on a tuning set of its axes (``scripts/dfki.py
--tune-robust-catch --write``, then ``--release-stage``;
:func:`mbs_envs.studies.dfki_tuning.robust_catch`; ``"PPO + LQR (robust catch)"`` for every seed of the agent), which
only ``scripts/dfki.py --robust-catch`` reads (:func:`stored_entry`).

Ids or controllers without an entry get :data:`FALLBACK` (the pre-tuning
defaults: bandwidth 10 rad/s, critical damping).
"""

from __future__ import annotations

import copy
import functools
import json
import pathlib
from typing import Any

PATH = pathlib.Path(__file__).with_name("tuned.json")

FALLBACK: dict[str, dict[str, Any]] = {
    "PD": {"omega": 10.0, "zeta": 1.0},
    "PD+gravity": {"omega": 10.0, "zeta": 1.0},
    "computed torque": {"omega": 10.0, "zeta": 1.0},
    "LQR": {"Q": [10.0, 10.0, 1.0, 1.0, 0.1], "R": [1.0, 1.0], "q_integral": 1.0},
    "PD steering": {"k_dlean": 0.3, "k_lean": 0.05, "k_h": 0.5, "k_r": 0.0, "k_w": 0.05},
    "swing-up + LQR": {"k_q": 40.0, "k_v": 10.0, "k_E": 4.0, "catch": 100.0},
    "energy swing-up + LQR": {"k_q": 10.0, "k_v": 5.0, "k_E": 10.0, "catch": 10.0},  # a_max: none (the linear law)
    "RL + LQR": {},  # empty: the pair catches at the swing-up + LQR's own level
}


@functools.lru_cache(maxsize=1)
def _table() -> dict[str, Any]:
    if not PATH.exists():
        return {}
    return json.loads(PATH.read_text()).get("gains", {})


def env_id(env: Any) -> str | None:
    """The registered id of ``env`` (wrapped or not), or None."""
    spec = getattr(env.unwrapped, "spec", None) or getattr(env, "spec", None)
    return None if spec is None else spec.id


#: a task version -> the version whose plant it shares (a changed reward keeps the plant, so the gains)
SAME_PLANT = {
    "mbs_envs/Acrobot-v1": "mbs_envs/Acrobot-v0",
    "mbs_envs/Pendubot-v1": "mbs_envs/Pendubot-v0",
    "mbs_envs/Acrobot-v2": "mbs_envs/Acrobot-v0",
    "mbs_envs/Pendubot-v2": "mbs_envs/Pendubot-v0",
    "mbs_envs/AcrobotDFKI-v2": "mbs_envs/AcrobotDFKI-v1",
    "mbs_envs/PendubotDFKI-v2": "mbs_envs/PendubotDFKI-v1",
}


#: a controller -> the controller whose tuned entry it takes while it has none of its own (the same laws and gains)
SAME_LAWS = {"adaptive swing-up + LQR": "swing-up + LQR", "identified iLQR + TVLQR": "adaptive swing-up + LQR"}
for _name, _same in SAME_LAWS.items():  # in order: a chain's earlier link is in FALLBACK before a later one needs it
    FALLBACK[_name] = FALLBACK[_same]


def tuned_gains(env: Any, controller: str) -> dict[str, Any]:
    """The default gains of ``controller`` (a display name, e.g. ``"computed torque"``) on ``env``
    (for a task version that only changed the reward, those tuned on its earlier version: :data:`SAME_PLANT`;
    for a controller without an entry, those of the controller whose laws it shares: :data:`SAME_LAWS`)."""
    if controller not in FALLBACK:
        raise ValueError(f"no tuned gains for controller {controller!r}; known: {sorted(FALLBACK)}")
    entry = stored_entry(env_id(env) or "", controller)
    return copy.deepcopy(FALLBACK[controller]) if entry is None else entry


def stored_entry(key: str, controller: str) -> dict[str, Any] | None:
    """The entry of ``tuned.json`` that ``controller`` takes on the env id ``key``: its own, else along the chain of
    controllers whose laws it shares (:data:`SAME_LAWS`), each on ``key`` or on the version whose plant it shares
    (:data:`SAME_PLANT`); None where no entry is stored (a copy otherwise)."""
    table = _table()
    name: str | None = controller
    while name is not None:
        entry = table.get(key, {}).get(name)
        if entry is None:  # a reward-only version: the gains tuned on the version whose plant it shares
            entry = table.get(SAME_PLANT.get(key, ""), {}).get(name)
        if entry is not None:
            return copy.deepcopy(entry)
        name = SAME_LAWS.get(name)
    return None


def clear_cache() -> None:
    """Re-read ``tuned.json`` at the next call (after ``scripts/tune.py --write``)."""
    _table.cache_clear()
