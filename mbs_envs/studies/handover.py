"""RL + LQR on the swing-up scenes: a learned policy swings up, the scene's upright LQR catches.

The evaluated policy acts as the agent until the state enters the catch level of the
scene's model-based controller, ``x^T S x < catch`` (``x = (wrap(q - q_up), v)``; ``K, S`` the
upright LQR of the scene's swing-up controller, :func:`catching_controller`, with its tuned gains and level), and as
the LQR from then on; it hands back to the agent only when the state leaves
``release * catch`` (the same hysteresis as the model-based controller, whose energy pump the
agent replaces). The mode and the agent's own state travel in SB3's ``state``, so any rollout
loop that passes ``state`` back runs it; the pair is reported on the "model-based + RL" side.

The catch level of the pair is tuned as the model-based controller's gains are, with the same care
(:func:`tune_catch`, ``scripts/tune_handover.py``): a grid of levels (and hysteresis factors),
scored by the success of every shipped agent of the scene on tuning seeds, at the nominal plant
and +-20 % mismatch; the pick is stored in ``controllers/tuned.json`` as the scene's ``"RL + LQR"``
entry (without one: the model-based controller's own level). Why a tuned level and not the LQR's
sampled region of attraction (:func:`controllers.region.estimate_region`): alone, under the torque
limit, the acrobot's LQR holds every sampled start only below ``x^T S x`` = 2.2 (nominal plant; 0.89
over nominal and +-20 %), some 450 times under the level (1,000) with which the swing-up + LQR
succeeds on 95 % of 20 tuning seeds; with that region the catch comes too rarely. The loop catches more than the LQR alone does, because a
state that leaves ``release * catch`` is handed back and caught again.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs.controllers.swingup import SwingUpLQR
from .. import validation as check


#: the name of the pair's entry in controllers/tuned.json
TUNED_NAME = "RL + LQR"


def catching_controller(env: Any, lqr_r: float | None = None) -> Any:
    """The scene's model-based swing-up controller whose LQR catches: :class:`controllers.swingup.SwingUpLQR` on the
    arm, :class:`controllers.energy_swingup.EnergySwingUpLQR` on a derived mechanism (with its tuned gains; on the arm
    with the LQR's input weight ``lqr_r`` [(N m)^-2] where given)."""
    from mbs_envs.controllers.energy_swingup import EnergySwingUpLQR

    if isinstance(env.unwrapped, SwingUpLQR.fits):
        return SwingUpLQR(env) if lqr_r is None else SwingUpLQR(env, lqr_r=lqr_r)
    if lqr_r is not None:
        raise ValueError(
            f"lqr_r: only the 2R arm's catching LQR takes an input weight, not {type(env.unwrapped).__name__}'s"
        )
    if isinstance(env.unwrapped, EnergySwingUpLQR.fits):
        return EnergySwingUpLQR(env)
    raise ValueError(f"no swing-up controller catches on {type(env.unwrapped).__name__}")


def hand_over(agent: Any, env: Any, catch: float | None = None, release: float | None = None, lqr_r: float | None = None
              ) -> "HandOverPolicy":  # fmt: skip
    """``agent`` with the scene's upright LQR catching at the pair's tuned level (module docstring),
    or at ``catch`` / ``release`` where given, the LQR with the input weight ``lqr_r`` where given."""
    from mbs_envs.controllers.tuned import tuned_gains

    lqr = catching_controller(env, lqr_r)
    entry = tuned_gains(env, TUNED_NAME) or {}
    catch = entry.get("catch", lqr.catch) if catch is None else catch
    release = entry.get("release", lqr.release) if release is None else release
    return HandOverPolicy(agent, lqr, catch, release)


def tune_catch(
    scene: str, agents: list[Any], grid: list[dict[str, float]], seeds: list[int]
) -> tuple[dict[str, float], list[dict[str, Any]]]:
    """The catch level and hysteresis of the pair, picked on tuning seeds over the plant set.

    Each entry of ``grid`` (``{"catch": c, "release": r}``) hands every agent of ``agents`` over to the
    LQR and runs ``seeds`` at each condition of :data:`mbs_envs.studies.tuning.TUNING_CONDITIONS`
    (nominal, +-20 %). The pick has the highest success over all agents and conditions, then the most
    time near upright (:func:`mbs_envs.studies.evaluation.swing_up_metrics`).

    Returns
    -------
    best : dict
        The picked grid entry.
    rows : list of dict
        One per entry, condition and agent: ``success`` and ``time_near_upright`` (means over seeds).
    """
    import gymnasium as gym

    from .conditions import SCENES, TUNING_CONDITIONS, plant_kwargs
    from .evaluation import rollout_batch, swing_up_metrics

    env_id = SCENES[scene][0]
    nominal = gym.make(env_id)
    rows = []
    for cond in TUNING_CONDITIONS:
        venv = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                            **plant_kwargs(scene, cond))  # fmt: skip
        for entry in grid:
            for k, agent in enumerate(agents):
                m = [swing_up_metrics(e) for e in rollout_batch(venv, hand_over(agent, nominal, **entry), seeds)]
                rows.append({**entry, "condition": cond.name, "agent": k, "success": float(np.mean([x["success"] for x in m])),
                             "time_near_upright": float(np.mean([x["time_near_upright"] for x in m]))})  # fmt: skip
        venv.close()

    def key(entry: dict[str, float]) -> tuple[float, float]:
        mine = [r for r in rows if all(r[k] == v for k, v in entry.items())]
        return float(np.mean([r["success"] for r in mine])), float(np.mean([r["time_near_upright"] for r in mine]))

    return max(grid, key=key), rows


class HandOverPolicy:
    """``agent`` until the LQR's catch level, then the LQR (module docstring).

    The switching rule is the model-based controller's own (:meth:`controllers.swingup.SwingUpLQR.balance`),
    with the agent in place of the energy pump.

    Parameters
    ----------
    agent : object with ``predict``
    lqr : SwingUpLQR or EnergySwingUpLQR
        Its switching rule, ``K``, ``S``, torque limit and decoding are used (not its swing-up law).
    level : float
        The catch level of ``x^T S x``.
    release : float
        Hysteresis factor (> 1).
    """

    def __init__(self, agent: Any, lqr: Any, level: float, release: float = 4.0):
        self.agent, self.lqr = agent, lqr
        self.level = check.positive(level, "level")
        self.release = check.real(release, "release", 1.0, np.inf, low_open=True)

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        """The action of each member and the state to pass back, ``(agent state, balancing (B,))``."""
        obs = np.asarray(observation)
        d = self.lqr.decode_observation(obs.reshape(-1, obs.shape[-1]))
        inner, balancing = state if state is not None else (None, None)
        balancing, u_lqr = self.lqr.balance(d.q, d.v, balancing, episode_start, self.level, self.release)
        a_rl, inner = self.agent.predict(
            observation, state=inner, episode_start=episode_start, deterministic=deterministic
        )
        a_lqr = np.clip(u_lqr[:, None] / self.lqr.u_max, -1.0, 1.0)
        action = np.where(balancing[:, None], a_lqr, np.asarray(a_rl, float).reshape(len(balancing), -1)).astype(
            np.float32
        )
        return (action[0] if obs.ndim == 1 else action), (inner, balancing)
