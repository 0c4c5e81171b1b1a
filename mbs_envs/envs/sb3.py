"""stable-baselines3 on the batched environments without per-environment Python.

:class:`SB3VecEnv` presents a :class:`~mbs_envs.envs.vector.MBSVectorEnv` (in
``SAME_STEP`` autoreset mode) as an SB3 ``VecEnv``: one batched physics step
per ``step_wait``, SB3's conventions for episode ends
(``info["terminal_observation"]``, ``info["TimeLimit.truncated"]``).

With ``action_repeat = K > 1`` (the vector env then in ``DISABLED`` autoreset
mode) each ``step_wait`` holds the agent's action for ``K`` control steps (one
batched step each) and returns the sum of their rewards: the agent decides
every ``K dt`` and its discount ``gamma`` spans ``K`` times as much simulated
time. A member whose episode ends inside the ``K`` steps stops counting reward
there; its terminal observation is the one at its end, and it is reset after
the ``K`` steps from its own generator (the steps it made past its end are
discarded), so its next episode starts exactly as with ``K = 1``. The policy
must then hold its decisions the same way at evaluation
(:class:`mbs_envs.studies.held.HeldPolicy`).
:func:`make_sb3_vec_env` builds it for a registered id, with ``VecMonitor`` so
SB3 logs episode returns::

    from stable_baselines3 import PPO
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mbs_envs/Planar2R-v0", n_envs=64, seed=0)
    PPO("MlpPolicy", venv).learn(100_000)

Requires the ``rl`` extra (stable-baselines3).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from .. import validation as check
from .vector import MBSVectorEnv


class SB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` over a batched mbs_envs vector env (see the module docstring).

    Attribute access (``get_attr``, ``set_attr``, ``env_method``) goes to the
    task env shared by all members: the same value for every index.
    """

    def __init__(self, venv: MBSVectorEnv, action_repeat: int = 1):
        if not isinstance(getattr(venv, "unwrapped", None), MBSVectorEnv):
            raise ValueError(f"venv must be an MBSVectorEnv (or a wrapper of one), got {type(venv).__name__}")
        self.action_repeat = check_action_repeat(action_repeat)
        modes = (AutoresetMode.SAME_STEP, AutoresetMode.DISABLED) if action_repeat == 1 else (AutoresetMode.DISABLED,)
        if venv.autoreset_mode not in modes:
            raise ValueError(f"SB3VecEnv with action_repeat={action_repeat} needs autoreset_mode="
                             f"{' or '.join(m.name for m in modes)} (SB3 resets within the step), got {venv.autoreset_mode.name}")  # fmt: skip
        self.venv = venv
        self.task = venv.unwrapped.env  # the task env the members share
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and all(o == self._options[0] for o in self._options) else None
        if options is None and any(self._options):
            raise ValueError("SB3VecEnv applies one options dict to all members")
        obs, _ = self.venv.reset(seed=seeds, options=options or None)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        same_step = self.venv.autoreset_mode == AutoresetMode.SAME_STEP
        total = np.zeros(self.num_envs)
        dones = np.zeros(self.num_envs, bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for _ in range(self.action_repeat):
            obs, reward, terminated, truncated, info = self.venv.step(self._actions)
            total[~dones] += reward[~dones]
            ended = (terminated | truncated) & ~dones
            for i in np.flatnonzero(ended):
                infos[i]["terminal_observation"] = info["final_obs"][i] if same_step else obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                infos[i]["diverged"] = bool((info["final_info"] if same_step else info)["diverged"][i])
            dones |= ended
            if dones.all():
                break
        if not same_step and dones.any():
            obs[dones] = self.venv.reset(options={"reset_mask": dones})[0][dones]
        return obs, total.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        value = getattr(self.task, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """A setting of the shared task env, by SB3's rule: ``value`` is one value for the members ``indices``
        (a list is a value too, e.g. per-joint torque limits); validated by :meth:`MBSVectorEnv.set_attr` (unknown,
        fixed or misspelt names raise ``ValueError``); ``indices`` must cover every member, since they share it."""
        if indices is not None and sorted(set(self._get_indices(indices))) != list(range(self.num_envs)):
            raise ValueError(
                f"set_attr({attr_name!r}, indices={indices!r}): the members share one task env; set it for all"
            )
        self.venv.set_attr(attr_name, [value] * self.num_envs)

    def seed(self, seed: int | None = None) -> Any:
        """SB3's ``seed``: member ``i`` gets ``seed + i`` at the next reset; ``seed`` None or an int >= 0
        (:func:`mbs_envs.validation.seed`, the rule of every env here), checked now."""
        return super().seed(check.seed(seed))

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        method = getattr(self.task, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: Any = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.venv.render()
        return [None] * self.num_envs if frames is None else list(frames)


#: the longest hold of an action [control steps]
MAX_ACTION_REPEAT = 10_000


def check_action_repeat(action_repeat: Any) -> int:
    """``action_repeat`` (control steps per decision) as an int in ``[1, MAX_ACTION_REPEAT]``, else a
    ``ValueError`` naming it (:func:`mbs_envs.validation.integer`)."""
    return check.integer(action_repeat, "action_repeat", 1, MAX_ACTION_REPEAT)


def make_sb3_vec_env(
    env_id: str,
    n_envs: int = 8,
    seed: int | None = None,
    monitor: bool = True,
    action_repeat: int = 1,
    perturb: Any = None,
    **kwargs: Any,
) -> VecEnv:
    """SB3 ``VecEnv`` of ``n_envs`` batched members of a registered id.

    Parameters
    ----------
    env_id : str
        A registered mbs_envs id (``"mbs_envs/Planar2R-v0"``, ...).
    n_envs : int
    seed : int, optional
        Member ``i`` is seeded with ``seed + i`` at the first reset.
    monitor : bool
        Wrap in ``VecMonitor`` (episode returns and lengths for SB3's logger).
    action_repeat : int
        Control steps each action is held for (see the module docstring).
    perturb : TrainingPerturbations or "dfki" or mapping, optional
        Train under the robustness axes: each member meets one perturbation per episode
        (:class:`mbs_envs.envs.perturbed.PerturbedVectorEnv`, its generator seeded from ``seed``).
    **kwargs
        Env arguments (``params``, ``dt``, ``n_links``, ``randomize``, ...).
    """
    from .perturbed import PerturbedVectorEnv, TrainingPerturbations

    kwargs.setdefault("full_info", False)
    perturb = None if perturb is None else TrainingPerturbations.of(perturb)  # refused before anything is built
    same_step = check_action_repeat(action_repeat) == 1 and perturb is None
    mode = AutoresetMode.SAME_STEP if same_step else AutoresetMode.DISABLED
    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs)
    if perturb is not None:
        venv = PerturbedVectorEnv(venv, perturb, seed=seed)
    env: VecEnv = SB3VecEnv(venv, action_repeat)
    if seed is not None:
        env.seed(seed)
    return VecMonitor(env) if monitor else env
