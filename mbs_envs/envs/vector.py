"""Numpy-batched vector environments: one model, one integrator call for all members.

:class:`MBSVectorEnv` runs ``num_envs`` copies of any :class:`~mbs_envs.envs.base.MBSEnv`
task as one batch: the physics step is a single batched :func:`mbs_envs.dynamics.simulate.advance`
call, and observation, reward, termination and info come from the same task
functions the single environment uses (``task_now``, ``observe``, ``reward``,
``terminated``, ``state_diverged``, ``task_info``), called with ``(N, ...)``
arrays. Resets draw through the single env's ``draw_starts``: each member's random numbers from its
own generator, the rest for all the members reset at once, so member ``i`` seeded with ``seed + i``
reproduces ``gym.make(id).reset(seed=seed + i)`` and its episode. Autoresets take each member's next
start from a batch drawn ahead (:mod:`mbs_envs.envs.lookahead`: the same starts; ``draw_ahead=False``
draws them at the autoreset).

Every registered id has it as ``vector_entry_point``::

    envs = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=1024, vectorization_mode="vector_entry_point")

Autoreset follows Gymnasium 1.x (``metadata["autoreset_mode"]``): ``NEXT_STEP``
(default; the step after an episode ends resets that member and ignores its
action) or ``SAME_STEP`` (the member is reset within the step; its last
observation and info are in ``info["final_obs"]``, ``info["final_info"]``).

Domain randomization: ``randomize={"m2": 0.2, ...}`` scales the named model
parameters of every member by ``U(1 - s, 1 + s)`` (or, for a pair ``{"b2": (0.0, 0.1)}``, draws the
parameter itself from ``U(low, high)``), drawn from the member's
generator at each reset (after its task), for models whose equations accept
per-member parameters (see :meth:`mbs_envs.models.base.Params.batched`). Fixed per-member
parameters (a parameter sweep run as one batch): ``member_params=[{"m2": 0.9}, {"m2": 1.1}, ...]``,
one mapping per member over the nominal parameters (randomized ones scale the member's own value).

Impulses: :meth:`MBSVectorEnv.apply_impulse` adds a generalized impulse ``J`` to every member's
velocities, ``v <- v + M(q)^-1 J`` (unconstrained models), e.g. a torque pulse ``tau(t)`` applied
step by step as ``J = tau(t_k) dt`` (first-order operator splitting).

With an adaptive (scipy) integrator the batch is one system with one step
size, so members differ from single envs within the tolerance; fixed-step
methods give the single env's numbers (tested to 1e-12).

The first vector env of a process sets glibc's malloc to keep freed memory
(:mod:`mbs_envs.dynamics.memory`; ``MBS_ENVS_KEEP_FREED_MEMORY=0`` leaves it): otherwise a
batch of a few thousand members can fault its work arrays in afresh at every step.
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import validation as check
from ..dynamics.memory import keep_freed_memory
from .actions import validate_action
from .base import MBSEnv
from .budget import check_work_budget
from .lookahead import StartsAhead
from .stacking import tree_assign, tree_pick


def _same(a: Any, b: Any) -> bool:
    """Whether two attribute values are equal (arrays elementwise, same shape)."""
    try:
        return (
            bool(np.array_equal(np.asarray(a), np.asarray(b)))
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray)
            else bool(a == b)
        )
    except Exception:
        return a is b


class MBSVectorEnv(VectorEnv):
    """``num_envs`` members of one task, stepped as a numpy batch (see the module docstring).

    Parameters
    ----------
    env_cls : type of MBSEnv
    num_envs : int
    max_episode_steps : int, optional
        Truncation (the registered id's value through ``gym.make_vec``).
    autoreset_mode : AutoresetMode or str
    randomize : dict, optional
        ``{parameter name: relative half-width s}`` (domain randomization: the parameter times ``U(1 - s, 1 + s)``)
        or ``{parameter name: (low, high)}`` (the parameter itself ``U(low, high)``: e.g. a damping whose nominal
        value is zero).
    member_params : sequence of Mapping, optional
        One mapping of model parameters per member (fixed for the env's life), each validated as
        ``params`` are; members may name different parameters (the others stay nominal).
    full_info : bool
        ``info`` carries everything the single env's does (energy, reward
        terms, task quantities); False keeps ``t`` and ``diverged`` only (faster).
    draw_ahead : bool
        Autoresets take each member's next start from a batch drawn ahead
        (:mod:`mbs_envs.envs.lookahead`; the same starts, drawn in bulk); False draws
        them at the autoreset, the members reset in a step as one batch.
    **env_kwargs
        The single env's constructor arguments (``params``, ``dt``, ...).
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        env_cls: type[MBSEnv],
        num_envs: int,
        *,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        randomize: dict[str, float] | None = None,
        member_params: Any = None,
        full_info: bool = True,
        draw_ahead: bool = True,
        render_mode: str | None = None,
        **env_kwargs: Any,
    ):
        num_envs = check.integer(num_envs, "num_envs", 1, 10**12)
        keep_freed_memory()  # a batched step's work arrays would otherwise go back to the OS after every step
        if max_episode_steps is not None:
            max_episode_steps = check.integer(max_episode_steps, "max_episode_steps", 1, 10**12)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be 'rgb_array' or None, got {render_mode!r}")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.env = env_cls(**env_kwargs)  # the task's code and configuration
        check_work_budget(self.env, num_envs)  # before any per-member allocation
        self.env._budget_members = num_envs  # a later set_attr("substeps", ...) is checked for the whole batch
        self.nominal_model = self.env.model
        self._model = self.nominal_model  # the batch's (per-member parameters when randomized)
        self.nominal_params = self.model.params
        self.randomize = self._checked_randomize(randomize)
        self.num_envs = int(num_envs)
        self._fixed = self._checked_member_params(member_params)
        #: the per-member parameters given at construction (a tuple of dicts), or None
        self.member_params = None if member_params is None else tuple(dict(m) for m in member_params)
        self.max_episode_steps = max_episode_steps
        self.full_info = bool(full_info)
        self.draw_ahead = check.boolean(draw_ahead, "draw_ahead")
        self.render_mode = render_mode
        self.single_observation_space = self.env.observation_space
        self.single_action_space = self.env.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        n = self.num_envs
        self._rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        # the state in columns (nq, n), the compiled step's layout; _q and _v are their rows views (n, nq),
        # made on access so that copies and pickles (which copy arrays one by one) cannot split them
        self._qc, self._vc = np.zeros((self.model.nq, n)), np.zeros((self.model.nv, n))
        self._t = np.zeros(n)
        self._u = np.zeros((n, self.model.nu))
        self._elapsed = np.zeros(n, int)
        self._task: Any = None
        self._task_columns: tuple | None = None  # the compiled step's layout of _task, kept in step with it
        # the draws: a scale per member, or the value itself for a (low, high) range (the base value until drawn)
        self._scales: dict[str, np.ndarray] = {k: np.array(np.broadcast_to(self._base_value(k), (n,)), float) if isinstance(s, tuple)
                                               else np.ones(n) for k, s in self.randomize.items()}  # fmt: skip
        self._apply_scales()  # fixed per-member parameters from the start
        self._autoreset = np.zeros(n, bool)
        self._ahead = StartsAhead(n)  # the members' next starts, drawn in batches (autoresets take them)
        self._started = False

    @property
    def _q(self) -> np.ndarray:
        """Rows view ``(num_envs, nq)`` of the column state."""
        return self._qc.T

    @property
    def _v(self) -> np.ndarray:
        """Rows view ``(num_envs, nv)`` of the column state."""
        return self._vc.T

    @property
    def model(self) -> Any:
        """The batch's model (per-member parameters when randomized); fixed by the constructor's arguments."""
        return self._model

    @model.setter
    def model(self, value: Any) -> None:
        raise ValueError("model is fixed at construction (the compiled step and the state's shapes derive from it); "
                         "make a new env, with params= or randomize=")  # fmt: skip

    # -- attributes: the task env's settings, shared by every member ----------------

    def get_attr(self, name: str) -> tuple:
        """The task env's attribute ``name``, once per member (they share it)."""
        value = getattr(self.env, name)
        return tuple(value for _ in range(self.num_envs))

    def set_attr(self, name: str, values: Any) -> None:
        """Set a setting of the task env (:meth:`MBSEnv.settings`, validated), by Gymnasium's rule: a list or
        tuple holds one value per member (``num_envs`` of them), anything else is one value for every member (a
        per-joint setting as one value: a numpy array, ``set_attr("u_max", np.array([5.0, 2.0]))``, or one entry
        per member, ``[[5.0, 2.0]] * num_envs``). The members share the task env, so per-member values must be
        equal. Unknown or fixed names, a list of another length and differing values raise ``ValueError`` before
        any change."""
        if isinstance(values, (list, tuple)):
            if len(values) != self.num_envs:
                raise ValueError(f"set_attr({name!r}): a list or tuple holds one value per member (Gymnasium's rule), "
                                 f"got {len(values)} for {self.num_envs} members; pass one value for all as a numpy "
                                 "array or a scalar")  # fmt: skip
            first = values[0]
            if any(not _same(first, x) for x in values[1:]):
                raise ValueError(f"set_attr({name!r}): the members share one task env, so every value must be equal "
                                 "(per-member parameters: randomize=)")  # fmt: skip
            values = first
        self.env.set_setting(name, values)

    # -- domain randomization --------------------------------------------------

    def _checked_randomize(self, randomize: dict[str, float] | None) -> dict[str, float]:
        randomize = check.mapping(randomize, "randomize")
        names = set(self.nominal_params.names())
        for name, s in randomize.items():
            if name not in names:
                raise ValueError(f"randomize: unknown parameter {name!r} of {type(self.nominal_params).__name__}")
            if isinstance(s, (tuple, list, np.ndarray)):  # a range (low, high): the parameter itself drawn
                if np.size(s) != 2:
                    raise ValueError(
                        f"randomize[{name!r}] must be a half-width in [0, 1) or a range (low, high), got {s!r}"
                    )
                lo, hi = (
                    check.real(x, f"randomize[{name!r}]", -1e300, 1e300) for x in np.ravel(np.asarray(s, dtype=object))
                )
                if lo > hi:
                    raise ValueError(f"randomize[{name!r}] must be a range (low, high) with low <= high, got {s!r}")
                try:
                    self.nominal_params.replace(**{name: lo}).replace(**{name: hi})
                except ValueError as e:
                    raise ValueError(f"randomize[{name!r}]: {e}") from None
                randomize[name] = (lo, hi)
            else:
                randomize[name] = check.real(s, f"randomize[{name!r}]", 0.0, 1.0, high_open=True)
        if randomize and not getattr(self.model, "batched_params", False):
            raise ValueError(f"{type(self.model).__name__} does not support per-member parameters (randomize)")
        return randomize

    def _checked_member_params(self, member_params: Any) -> dict[str, np.ndarray]:
        """``{name: values (num_envs,)}`` of the parameters some member sets (the others' nominal), each
        member's set validated as ``params`` (a ValueError names the member and the parameter)."""
        if member_params is None:
            return {}
        if (
            isinstance(member_params, (str, bytes))
            or not hasattr(member_params, "__len__")
            or len(member_params) != self.num_envs
        ):
            raise ValueError(
                f"member_params must be a sequence of {self.num_envs} mappings (one per member), got {member_params!r:.80}"
            )
        if not getattr(self.model, "batched_params", False):
            raise ValueError(f"{type(self.model).__name__} does not support per-member parameters (member_params)")
        names: set[str] = set()
        for i, m in enumerate(member_params):
            m = check.mapping(m, f"member_params[{i}]")
            try:
                self.nominal_params.replace(**m)
            except ValueError as e:
                raise ValueError(f"member_params[{i}]: {e}") from None
            names |= set(m)
        return {
            k: np.array([float(m.get(k, getattr(self.nominal_params, k))) for m in member_params])
            for k in sorted(names)
        }

    def _base_value(self, name: str) -> Any:
        """Parameter ``name`` of every member before randomization: fixed per member, or nominal."""
        return self._fixed[name] if name in self._fixed else getattr(self.nominal_params, name)

    def _member_values(self, idx: Any, scales: dict[str, np.ndarray] | None = None) -> dict[str, Any]:
        """The per-member parameters of members ``idx`` (an index array or an int)."""
        scales = self._scales if scales is None else scales
        values = {k: v[idx] for k, v in self._fixed.items()}
        for k, s in self.randomize.items():
            values[k] = (
                scales[k][idx]
                if isinstance(s, tuple)
                else np.asarray(self._base_value(k) * np.ones(self.num_envs))[idx] * scales[k][idx]
            )
        return values

    def _apply_scales(self) -> None:
        if not (self.randomize or self._fixed):
            return
        self._model = self.nominal_model.with_params(
            self.nominal_params.batched(**self._member_values(np.arange(self.num_envs)))
        )

    # -- resets ----------------------------------------------------------------

    def _member_generators(self, seed: Any) -> list[np.random.Generator] | None:
        """Every member's generator after ``reset(seed=seed)``: new ones for the seeds given
        (:func:`mbs_envs.validation.seeds`: all parsed first), the current ones elsewhere; None without a
        seed. Nothing of the env changes."""
        seeds = check.seeds(seed, self.num_envs)
        if seeds is None:
            return None
        return [g if s is None else seeding.np_random(s)[0] for g, s in zip(self._rngs, seeds)]

    def _draw_member_params(
        self, idx: np.ndarray, rngs: list[np.random.Generator] | None = None
    ) -> tuple[dict[str, np.ndarray], Any]:
        """The randomization scales ``{name: (len(idx),)}`` of members ``idx``, drawn from their generators
        (``rngs``, default the current ones; the first draws of a reset: start states may depend on the
        parameters), and the model with those members' parameters."""
        rngs = self._rngs if rngs is None else rngs
        scales = {k: s.copy() for k, s in self._scales.items()}
        for i in idx:
            for k, s in self.randomize.items():
                scales[k][i] = rngs[i].uniform(*s) if isinstance(s, tuple) else rngs[i].uniform(1 - s, 1 + s)
        model = self.nominal_model
        if self.randomize or self._fixed:
            model = self.nominal_model.with_params(self.nominal_params.batched(**self._member_values(idx, scales)))
        return {k: s[idx] for k, s in scales.items()}, model

    def _reset_members(
        self, idx: np.ndarray, options: dict, rngs: list[np.random.Generator] | None = None
    ) -> np.ndarray:
        """Draw task and start state of members ``idx`` with the task's code, each from its own generator
        (``rngs``: every member's generator to draw from and keep; default the current ones), and return
        their first observations, ``(len(idx), obs_dim)``. The random numbers are drawn member by member,
        everything else for the members at once (:meth:`MBSEnv.draw_starts`); all are checked before any
        is assigned: a refused start (``ValueError``) leaves the batch and every generator as they were.
        Members with a start drawn ahead (:mod:`mbs_envs.envs.lookahead`) must have been rewound."""
        env = self.env
        rngs = self._rngs if rngs is None else rngs
        if len(idx) == 0:  # e.g. an all-False reset_mask: nothing is drawn (new seeds still replace the generators)
            self._rngs = list(rngs)
            return np.empty((0,) + self.single_observation_space.shape, self.single_observation_space.dtype)
        members = [rngs[i] for i in idx]
        saved = [g.bit_generator.state for g in members]  # restored if a start is refused
        try:
            drawn, model = self._draw_member_params(idx, rngs)
            task, q0, v0 = env.draw_starts(options, members, model)
            obs = env._check_start(q0, v0, task, env.start_given(options))  # the single env's rule, batched
        except ValueError:
            for g, state in zip(members, saved):
                g.bit_generator.state = state
            raise
        self._rngs = list(rngs)
        self._scales = {k: s.copy() for k, s in self._scales.items()}
        for k, x in drawn.items():
            self._scales[k][idx] = x
        if self._task is None:  # the first reset: every member
            self._task = task
        else:
            tree_assign(self._task, idx, task)
        if self._task_columns is not None:
            for whole, part in zip(self._task_columns, env.task_columns(task)):
                whole[..., idx] = part
        self._qc[:, idx], self._vc[:, idx] = q0.T, v0.T
        self._restarted(idx)
        return obs

    def _restarted(self, idx: np.ndarray) -> None:
        """Members ``idx`` begin an episode (their task, state and parameters set)."""
        self._t[idx] = 0.0
        self._u[idx] = 0.0
        self._elapsed[idx] = 0
        self._apply_scales()

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset all members (or those in ``options["reset_mask"]``).

        ``seed``: an int seeds member ``i`` with ``seed + i``; a list gives each
        its own. Other ``options`` go to every member's reset (see the single env).
        """
        options = check.mapping(options, "options")
        mask = options.pop("reset_mask", None)
        options = self.env.check_reset_options(options)
        rngs = self._member_generators(seed)  # seeds parsed, nothing changed yet
        if mask is None:
            idx = np.arange(self.num_envs)
        else:
            mask = check.mask(mask, "options['reset_mask']", self.num_envs)
            if not self._started and not mask.all():
                raise ValueError("the first reset must reset every member")
            idx = np.flatnonzero(mask)
        # the members reset, and those given a new generator (a seed for a member the mask leaves running):
        # none keeps a start drawn from its generator as it was (their generators as if nothing had been drawn ahead)
        reseeded = np.flatnonzero([g is not old for g, old in zip(rngs, self._rngs)]) if rngs is not None else idx[:0]
        undo = self._ahead.rewind(self, np.union1d(idx, reseeded))
        try:
            self._reset_members(idx, options, rngs)
        except ValueError:
            self._ahead.unrewind(self, undo)
            raise
        self._autoreset[idx] = False
        self._started = True
        now = self.env.task_now(self._t, self._task)
        return self.env.observe(self._q, self._v, now, self._task), self._info(now, np.zeros(self.num_envs, bool))

    # -- stepping ----------------------------------------------------------------

    def step(self, actions: Any):
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before step()")
        env = self.env
        pending = self.autoreset_mode == AutoresetMode.NEXT_STEP and self._autoreset.any()
        if pending:  # the members being reset ignore their action: any real number will do, NaN included
            if type(actions) is np.ndarray and actions.dtype.kind == "f":
                a = actions.astype(
                    float
                )  # a native float64 copy (what check.reals gives, without its checks of other types)
            else:
                a = check.reals(actions, "actions", bools=True)
            if self.model.nu == 1 and a.shape == (self.num_envs,):
                a = a[:, None]
            if a.shape == (self.num_envs, self.model.nu):
                a[self._autoreset] = 0.0
            actions = a
        a = validate_action(actions, self.model.nu, self.num_envs)
        if getattr(env, "compiled", None) is not None:
            obs, reward, bad, terminated, values = self._step_compiled(a)
        else:
            obs, reward, bad, terminated, values = self._step_numpy(a)
        info: dict[str, Any] = {"t": self._t.copy(), "diverged": bad}
        if self.full_info:
            info.update(values)
            info["u"] = self._u.copy()
        self._info_masks(info)
        self._elapsed += 1
        if self.max_episode_steps is None:
            truncated = np.zeros(self.num_envs, bool)
        else:
            truncated = self._elapsed >= self.max_episode_steps
        if pending:
            idx = np.flatnonzero(self._autoreset)
            obs[idx] = self._restart(idx)
            reward[idx] = 0.0
            terminated[idx] = False
            truncated[idx] = False
            self._restarted_info(info, idx)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            idx = np.flatnonzero(done)
            final_obs = np.empty(self.num_envs, dtype=object)
            for i in idx:
                final_obs[i] = obs[i].copy()
            info["final_obs"], info["_final_obs"] = final_obs, done.copy()
            info["final_info"] = {k: np.copy(x) for k, x in info.items() if not k.startswith(("_", "final"))}
            info["_final_info"] = done.copy()
            obs[idx] = self._restart(idx)
            self._restarted_info(info, idx)
        self._autoreset = done if self.autoreset_mode == AutoresetMode.NEXT_STEP else np.zeros(self.num_envs, bool)
        return obs, np.asarray(reward, float), terminated, truncated, info

    def _step_numpy(self, a: np.ndarray) -> tuple:
        """The same step on the numpy path (:meth:`MBSEnv.step_rows`)."""
        q, v, self._t, self._u, obs, reward, terminated, bad, values = self.env.step_rows(
            self.model, self._q, self._v, self._t, self._task, a, self.full_info
        )
        self._q[...], self._v[...] = q, v  # into the columns (see __init__)
        return obs, reward, bad, terminated, values

    def _step_compiled(self, a: np.ndarray) -> tuple:
        """The same step as :meth:`_step_numpy`, compiled (:meth:`MBSEnv.run_step_kernel`)."""
        env = self.env
        if self._task_columns is None:
            self._task_columns = env.task_columns(self._task)
        obs, values, self._u, bad, terminated = env.run_step_kernel(
            self.model, self._qc, self._vc, self._t, self._task_columns, a, full_info=self.full_info
        )
        return obs, values[:, 0].copy(), bad, terminated, env.info_rows(values) if self.full_info else {}

    def _restarted_info(self, info: dict[str, Any], idx: np.ndarray) -> None:
        """Members ``idx`` were reset in this step (autoreset): their ``info`` rows become their reset's,
        as ``SyncVectorEnv`` gives them (``t = 0``, the new state's energy and task quantities, ``u = 0``);
        entries a reset does not have (the reward terms) are zero there, with their ``info["_key"]`` mask
        False. Computed for those members only."""
        fresh = self._member_info(idx)
        for key in [k for k in info if not k.startswith(("_", "final"))]:
            if key in fresh:
                info[key][idx] = fresh[key]
            else:
                info[key][idx] = 0
                mask = np.ones(self.num_envs, bool)
                mask[idx] = False
                info["_" + key] = mask

    def _member_info(self, idx: np.ndarray) -> dict[str, Any]:
        """The reset ``info`` entries (:meth:`_info`) of members ``idx``, one row each."""
        out: dict[str, Any] = {"t": self._t[idx], "diverged": np.zeros(len(idx), bool)}
        if self.full_info:
            q, v, u, task = self._q[idx], self._v[idx], self._u[idx], tree_pick(self._task, idx)
            model = self.model
            if self.randomize or self._fixed:  # the members' own parameters
                model = self.nominal_model.with_params(self.nominal_params.batched(**self._member_values(idx)))
            out["energy"] = model.energy(q, v)
            out["u"] = u
            out.update(self.env.task_info(q, v, self.env.task_now(self._t[idx], task), task, u))
        return out

    def _restart(self, idx: np.ndarray) -> np.ndarray:
        """Reset members ``idx`` (autoreset) and return their first observations: from their starts drawn
        ahead (:mod:`mbs_envs.envs.lookahead`), or, for a start the task refuses, drawn now (raising as
        a reset does). The same starts either way."""
        if not self.draw_ahead:
            return self._reset_members(idx, {})
        ahead = self._ahead
        ready = ahead.ready(self, idx)
        if ready.all():
            obs = ahead.take(self, idx)
            self._restarted(idx)
        else:
            obs = np.empty((len(idx),) + self.single_observation_space.shape, self.single_observation_space.dtype)
            later = idx[~ready]  # first: a refusal leaves the members taken below as they were
            ahead.rewind(self, later)
            obs[~ready] = self._reset_members(later, {})
            if ready.any():
                obs[ready] = ahead.take(self, idx[ready])
                self._restarted(idx[ready])
        ahead.top_up(self)
        return obs

    def _info(self, now: Any, bad: np.ndarray, terms: dict | None = None) -> dict[str, Any]:
        info: dict[str, Any] = {"t": self._t.copy(), "diverged": np.asarray(bad, bool).copy()}
        if self.full_info:
            info["energy"] = self.model.energy(self._q, self._v)
            info["u"] = self._u.copy()
            info.update(terms or {})
            info.update(self.env.task_info(self._q, self._v, now, self._task, self._u))
        return self._info_masks(info)

    def _info_masks(self, info: dict[str, Any]) -> dict[str, Any]:
        """Gymnasium's ``info["_key"]`` masks: every member has every key."""
        mask = np.ones(self.num_envs, bool)
        for key in list(info):
            info["_" + key] = mask
        return info

    # -- state access, rendering, closing ---------------------------------------

    @property
    def q(self) -> np.ndarray:
        """Coordinates of every member, shape ``(num_envs, nq)`` (a copy)."""
        return self._q.copy()

    @property
    def v(self) -> np.ndarray:
        """Velocities of every member, shape ``(num_envs, nv)`` (a copy)."""
        return self._v.copy()

    def apply_impulse(self, J: Any) -> None:
        """Add the generalized impulse ``J`` to every member's velocities.

        Unconstrained: ``v <- v + M(q)^-1 J``. With constraints ``Psi(q) v = 0`` (loop closure, rolling) the
        constraints answer with an impulse of their own (the impulsive form of the equations of motion):
        ``M (v+ - v) = J + Psi^T Lam``, ``Psi v+ = 0``, solved as the constrained accelerations are
        (:func:`~mbs_envs.dynamics.constraints.constrained_accelerations`, the Schur complement).

        Parameters
        ----------
        J : array_like, shape (num_envs, nv)
            Impulse per member [N m s or N s per coordinate], e.g. ``tau dt`` of a torque ``tau``
            applied over one control step.

        Raises
        ------
        ValueError
            Naming ``J``: wrong shape or a non-finite entry. Nothing changes on refusal.
        """
        J = check.reals(J, "J")
        if J.shape != (self.num_envs, self.model.nv) or not np.isfinite(J).all():
            raise ValueError(f"J must be finite with shape ({self.num_envs}, {self.model.nv}), got shape {J.shape}")
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before apply_impulse()")
        q, v = self._q, self._v
        M = self.model.mass_matrix(q)
        if self.model.constrained:
            from ..dynamics.constraints import constrained_accelerations
            from ..dynamics.linalg import batched_matvec

            Psi = self.model.constraint_jacobian(q)
            dv = constrained_accelerations(M, J, Psi, -batched_matvec(Psi, v), conditioning=False)[0]
        else:
            dv = np.linalg.solve(M, J[..., None])[..., 0]
        self._vc += dv.T

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One RGB frame per member (``render_mode="rgb_array"``)."""
        if self.render_mode is None:
            gym.logger.warn("render_mode is None; pass render_mode='rgb_array' to make_vec")
            return None
        env = self.env
        env.render_mode = "rgb_array"
        return tuple(env.render_state(self._q[i], float(self._t[i]), tree_pick(self._task, i), self._v[i], self._u[i])
                     for i in range(self.num_envs))  # fmt: skip

    def close_extras(self, **kwargs: Any) -> None:
        self.env.close()


def make_vector(entry_point: str, num_envs: int = 1, **kwargs: Any) -> MBSVectorEnv:
    """The ``vector_entry_point`` of every id: the batched env of the class at ``entry_point``."""
    from gymnasium.envs.registration import load_env_creator

    return MBSVectorEnv(load_env_creator(entry_point), num_envs, **kwargs)


def vector_entry_point(entry_point: str) -> str:
    """The registered ``vector_entry_point`` of the env class at ``entry_point`` (``"module:Class"``), as a string
    Gymnasium's ``EnvSpec.to_json`` serializes: ``"mbs_envs.envs.vector:module.Class"``, which Gymnasium loads as
    this module's attribute ``module.Class`` (:func:`__getattr__`), :func:`make_vector` bound to the class."""
    module, _, cls = entry_point.partition(":")
    return f"{__name__}:{module}.{cls}"


def __getattr__(name: str) -> Any:
    """``module.Class``: :func:`make_vector` bound to the env class ``module:Class`` (:func:`vector_entry_point`)."""
    module, _, cls = name.rpartition(".")
    if not module or not cls.isidentifier():
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return functools.partial(make_vector, f"{module}:{cls}")
