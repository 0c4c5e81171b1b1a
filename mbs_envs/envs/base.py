"""The environment base: a model, an integrator and a task.

:class:`MBSEnv` owns what every scene shares: the physics step (substeps at a
finer step than the control step, zero-order hold of the input), action
validation and scaling to the actuator limits, divergence detection, seeding,
exact start states, ``info["energy"]``, pickling and rendering plumbing. A task
subclass supplies the reset distribution, the observation, the reward and the
drawing; see :class:`mbs_envs.envs.tracking.JointTrackingEnv`.
"""

from __future__ import annotations

import copy
import functools
from typing import Any, ClassVar

import gymnasium as gym
from gymnasium.utils import seeding
from ..dynamics import background
import numpy as np

from ..dynamics import integrators
from .. import validation as check
from ..dynamics.compiled import TableauArrays
from ..models.base import Model, as_vector
from ..dynamics.simulate import DIVERGENCE_LIMIT, advance, diverged
from .rendering import PlanarRenderer
from .dispatch import StepDispatch
from .drawing import Drawable
from .stacking import tree_pick
from .budget import check_work_budget
from .actions import validate_action


def _scalar(x: Any) -> Any:
    """0-d arrays and numpy scalars as Python scalars (a single env's ``info``); arrays unchanged."""
    return x.item() if (isinstance(x, np.ndarray) and x.ndim == 0) or isinstance(x, np.generic) else x


def checked_residual_limit() -> check.Checked:
    """The ``residual_limit`` setting of a scene whose loop can open, validated on every assignment: from 10x the
    start's consistency tolerance (1e-9 m: a lower limit would end every episode at once) to 1 m."""
    return check.Checked(lambda x, name: check.real(x, name, 1e-8, 1.0))


class MBSEnv(Drawable, gym.Env):
    """Base of all mbs_envs environments (see the module docstring).

    Parameters
    ----------
    model : Model
        The equations this environment integrates.
    u_max : array_like, shape (nu,) or scalar
        Actuator limits; the action ``a in [-1, 1]^nu`` applies ``u = a * u_max``.
    dt : float
        Control step [s]: the action is held constant over it.
    integrator : str
        Name from :func:`mbs_envs.dynamics.integrators.available`.
    substeps : int
        Fixed-step integrator steps per control step (physics step ``dt / substeps``).
    rtol, atol : float, optional
        Tolerances of the adaptive integrators.
    divergence_limit : float
        ``|q|`` or ``|v|`` beyond this (or non-finite) ends the episode with
        ``info["diverged"] = True``; the observation keeps the last finite state.
    stabilization : {None, "projection", "baumgarte", "none"}
        Constrained models only (default projection); see
        :class:`mbs_envs.dynamics.constraints.Stabilization`.
    compiled : bool
        Step through the scene's compiled kernel where it applies (see
        :attr:`compiled`); False forces the numpy path.
    render_mode : {None, "human", "rgb_array"}
    """

    metadata: ClassVar[dict] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    # settings validated on every assignment (constructor, ``set_attr``, ``env.dt = ...``)
    dt = check.Checked(lambda x, name: check.positive(x, name, 1e3))
    divergence_limit = check.Checked(lambda x, name: check.real(x, name, 0.0, 1e30, low_open=True), fixed=True)
    integrator = check.Checked(
        lambda x, name: x if isinstance(x, integrators.Stepper) else integrators.get(x), fixed=True
    )
    # the equations: the compiled kernels, the spaces and the state's shapes derive from them
    model = check.Checked(lambda x, name: x, fixed=True)

    def __init__(
        self,
        model: Model,
        u_max: Any,
        *,
        dt: float = 0.01,
        integrator: str = "rk4",
        substeps: int = 1,
        rtol: float | None = None,
        atol: float | None = None,
        divergence_limit: float = DIVERGENCE_LIMIT,
        stabilization: Any = None,
        compiled: bool = True,
        render_mode: str | None = None,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        options = {k: v for k, v in (("rtol", rtol), ("atol", atol)) if v is not None}
        self.wants_compiled = check.boolean(compiled, "compiled")
        self.model = model
        self.integrator = integrators.get(integrator, **options)
        if isinstance(self.integrator, integrators.JointImplicitEuler):
            self.integrator.check_model(model)  # a clear ValueError at make, not at the first step
        self.stabilization = stabilization
        self.dt = dt
        self._substeps = check.integer(substeps, "substeps", 1, 100_000)
        self.u_max = u_max
        self.divergence_limit = divergence_limit
        self.render_mode = render_mode
        # a (validated, positive) dt may be subnormal: 1 / dt is then inf, capped here
        self.metadata = {**self.metadata, "render_fps": max(1, int(round(min(1.0 / self.dt, 1e6))))}
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(model.nu,), dtype=np.float32)
        self._q = np.zeros(model.nq)
        self._v = np.zeros(model.nv)
        self._t = 0.0
        self._u = np.zeros(model.nu)  # the input applied in the last step
        self._task: Any = None
        self._task_columns: tuple | None = None  # (task, its columns) for the compiled step
        self._renderer: PlanarRenderer | None = None
        self._started = False  # reset() not called yet: step and render refuse (gym.error.ResetNeeded)
        check_work_budget(self)

    # -- the compiled step (see mbs_envs.envs.engine) ------------------------------

    #: The scene's compiled step: a module-level binding ``(theta, stepper, control, task,
    #: state, out)`` of :func:`mbs_envs.envs.engine.engine_step` to its model's and task's
    #: kernels, or None (numpy path). It applies to the class that declares it: a subclass
    #: steps compiled only if it declares one too (its task may differ).
    step_kernel: ClassVar[Any] = None
    #: a scene's step kernel for batches of more than one member, if it has its own (the same bits per member;
    #: compiled only where a batch is stepped)
    batched_step_kernel: ClassVar[Any] = None
    #: the largest constraint residual [m] of a state that has not diverged (constrained scenes; a scene
    #: whose loop can open declares ``residual_limit = checked_residual_limit()``)
    residual_limit: float = np.inf

    @property
    def dispatch(self) -> StepDispatch:
        """The compiled step's dispatch (:mod:`mbs_envs.envs.dispatch`): which kernel, with which arguments, kept."""
        d = self.__dict__.get("_dispatch")
        if d is None or d.env is not self:  # (a shallow copy of the env builds its own)
            d = self._dispatch = StepDispatch(self)
        return d

    @property
    def compiled(self) -> TableauArrays | None:
        """The tableau of the compiled step, or None when steps take the numpy path.

        Compiled: a scene class that declares a ``step_kernel``, a model with
        kernels whose ``B`` selects one coordinate per input, an explicit
        Runge-Kutta integrator and, for constrained models, the projection
        (:func:`mbs_envs.dynamics.compiled.compiled_stepping`); unless constructed with
        ``compiled=False``. Both paths give the same episodes (to rounding, 1e-12).
        """
        return self.dispatch.tableau()

    def task_arguments(self) -> tuple:
        """The task kernel's static arguments (scenes with a ``step_kernel``)."""
        return ()

    def task_columns(self, task: Any) -> tuple:
        """An episode's (or a stacked batch's) task as the task kernel's per-member columns,
        each with the member index last."""
        return ()

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        """The task kernel's columns of the step's ``info`` array: ``(name, width, boolean)``,
        ``width`` None for a scalar; the first is the reward."""
        return (("reward", None, False),)

    def info_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        """The columns of the compiled step's ``info`` array (:mod:`mbs_envs.envs.engine`)."""
        layout = self.task_layout() + (("energy", None, False),)
        if self.model.nc:
            layout += (("constraint_residual", None, False), ("multipliers", self.model.nc, False))
        return layout

    def run_step_kernel(
        self,
        model: Model,
        q,
        v,
        t,
        task_columns: tuple,
        action,
        tab: TableauArrays | None = None,
        full_info: bool = True,
    ) -> tuple:
        """The compiled control step of a batch (a single env: one member), in place (:meth:`StepDispatch.run
        <mbs_envs.envs.dispatch.StepDispatch.run>`).

        Parameters
        ----------
        model : Model
            The members' model (per-member parameters allowed).
        q, v : ndarray, shape (n, B)
            The state in C-contiguous columns (:mod:`mbs_envs.dynamics.compiled`), updated in place
            (a diverged member keeps its state).
        t : ndarray, shape (B,)
            Updated in place.
        task_columns : tuple
            :meth:`task_columns` of the members' tasks.
        action : ndarray, shape (B, nu)
            Validated and clipped.
        tab : TableauArrays, optional
            :attr:`compiled` (looked up when not given).
        full_info : bool
            Whether the ``info`` quantities no step needs are computed (the energy; as
            :meth:`step_rows`'s ``full_info``); if not, its column is NaN.

        Returns
        -------
        obs : ndarray, float32, shape (B, obs_dim)
            Column-major (the transpose of the kernel's columns, as Gymnasium's ``CartPoleVectorEnv``
            returns its observations).
        info : ndarray, shape (B, S)
            The columns of :meth:`info_layout` (the reward first), column-major too.
        u : ndarray, shape (B, nu)
            Column-major as well.
        bad, terminated : ndarray of bool, shape (B,)
            Diverged; ended (diverged or the task's termination).
        """
        return self.dispatch.run(model, q, v, t, task_columns, action, tab, full_info)

    def info_rows(self, info: np.ndarray) -> dict[str, np.ndarray]:
        """The named ``info`` entries of :meth:`run_step_kernel`'s array, one row per member
        (``(B,)`` or ``(B, width)``; the reward left out)."""
        return self.dispatch.info_rows(info)

    def _step_compiled(self, action: Any, tab: TableauArrays, d: StepDispatch):
        a = validate_action(action, self.model.nu)  # raises before any change
        if self._task_columns is None or self._task_columns[0] is not self._task:
            self._task_columns = (self._task, self.task_columns(self._task))
        t = np.array([self._t])
        obs, info_row, u, bad, terminated = d.run(
            self.model, self._q.reshape(-1, 1), self._v.reshape(-1, 1), t, self._task_columns[1], a.reshape(1, -1), tab
        )
        self._t = float(t[0])
        self._u = u[0]
        row = info_row[0]
        values = row.tolist()  # one conversion, not one per entry (:meth:`info_rows` is slower for one member)
        named = {name: (bool(values[c]) if boolean else values[c]) if w is None else row[c : c + w]
                 for name, c, w, boolean in d.info_columns()[1]}  # fmt: skip
        return self._single_step_result(obs, values, terminated, bad, named)

    def _single_step_result(self, obs, reward, terminated, bad, named: dict) -> tuple:
        """A single env's ``step`` result from its batch of one (either path); ``named`` its ``info`` entries."""
        info: dict[str, Any] = {"t": self._t, "diverged": bool(bad[0])}
        info.update(named)
        info["u"] = self._u
        if self.render_mode == "human":
            self.render()
        return obs[0], float(reward[0]), bool(terminated[0]), False, info

    @property
    def u_max(self) -> np.ndarray:
        """Actuator limits [N m], shape ``(nu,)``; the action ``a`` applies ``a * u_max``."""
        return self._u_max

    @u_max.setter
    def u_max(self, value: Any) -> None:
        self._u_max = check.frozen(check.vector(value, "torque_limit", self.model.nu, 0.0, low_open=True))
        check.touch(self)

    @property
    def substeps(self) -> int:
        """Fixed-step integrator steps per control step, in ``[1, 100000]`` and within the work budget
        (:func:`check_work_budget`)."""
        return self._substeps

    @substeps.setter
    def substeps(self, value: Any) -> None:
        value = check.integer(value, "substeps", 1, 100_000)
        before = self.__dict__.get("_substeps")
        self._substeps = value
        try:
            check_work_budget(self, self.__dict__.get("_budget_members", 1))
        except ValueError:
            self._substeps = before
            raise
        check.touch(self)

    @property
    def stabilization(self) -> Any:
        """The constraint stabilization (:meth:`Model.stabilization`; None on unconstrained models)."""
        return self._stabilization

    @stabilization.setter
    def stabilization(self, value: Any) -> None:
        self._stabilization = self.model.stabilization(value)  # ValueError naming what it takes
        check.touch(self)

    @classmethod
    def settings(cls) -> tuple[str, ...]:
        """The names ``set_attr`` may change after construction: the validated settings that are not
        fixed (:class:`mbs_envs.validation.Checked`) and the properties with a validating setter."""
        names = set()
        for klass in cls.__mro__:
            if not issubclass(klass, MBSEnv):  # gym.Env's np_random is state, not a setting
                continue
            for name, attr in vars(klass).items():
                if name.startswith("_"):
                    continue
                if (isinstance(attr, check.Checked) and not attr.fixed) or (
                    isinstance(attr, property) and attr.fset is not None
                ):
                    names.add(name)
        return tuple(sorted(names))

    def set_setting(self, name: Any, value: Any) -> None:
        """``setattr(self, name, value)`` for a name in :meth:`settings` (validated by its setter); any other
        name -- fixed at construction, read-only, unknown or misspelt -- is refused with ``ValueError``
        before anything changes. The path of ``set_attr`` on the vector and SB3 adapters."""
        if not isinstance(name, str):
            raise ValueError(f"attribute name must be a str, got {name!r}")
        allowed = self.settings()
        if name not in allowed:
            fixed = isinstance(getattr(type(self), name, None), check.Checked)
            why = "is fixed at construction (make a new env)" if fixed else "is not a setting of this env"
            raise ValueError(f"{name!r} {why}; the settings set_attr may change: {list(allowed)}")
        setattr(self, name, value)

    # -- state ---------------------------------------------------------------

    @property
    def q(self) -> np.ndarray:
        """Current generalized coordinates (a copy), shape ``(nq,)``."""
        return self._q.copy()

    @property
    def v(self) -> np.ndarray:
        """Current generalized velocities (a copy), shape ``(nv,)``."""
        return self._v.copy()

    @property
    def t(self) -> float:
        """Time since reset [s]."""
        return self._t

    # -- the task (override) ---------------------------------------------------
    #
    # The task is written once, in its module, as pure functions of explicit arrays
    # batched over leading dimensions and of the task's parameters (a frozen dataclass,
    # the env's ``task_params``; Gymnasium's phys2d style). These hooks call them: this
    # env with its own state, shape (n,), and :class:`mbs_envs.envs.vector.MBSVectorEnv`
    # with a batch, shape (N, n). ``task`` is what an episode draws at reset (e.g. a
    # reference), stacked member-wise in the vector env; ``now`` is what the task needs at time t.

    def _draw_tasks(self, options: dict, rngs: list[np.random.Generator]) -> Any:
        """The episode's task of ``L = len(rngs)`` members, member ``i`` drawn from ``rngs[i]``, stacked
        (:mod:`mbs_envs.envs.stacking`; default: none). Only the random numbers are drawn per member."""
        return None

    def _draw_states(self, task: Any, rngs: list[np.random.Generator], model: Model) -> tuple[np.ndarray, np.ndarray]:
        """Start states ``q0 (L, nq)``, ``v0 (L, nv)`` of the members of the stacked ``task``, member ``i``'s
        random numbers from ``rngs[i]`` (after its task's), for ``model`` (parameters scalar or ``(L,)``:
        a vector env's members may have their own)."""
        raise NotImplementedError

    def task_now(self, t: np.ndarray, task: Any) -> Any:
        """The task's time-dependent quantities at ``t`` (shape ``(...)``), e.g. the reference."""
        return None

    def observe(self, q: np.ndarray, v: np.ndarray, now: Any, task: Any) -> np.ndarray:
        """Observation, float32, shape ``(..., obs_dim)``."""
        raise NotImplementedError

    def reward(
        self, q: np.ndarray, v: np.ndarray, now: Any, task: Any, u: np.ndarray, action: np.ndarray
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Reward of the step just taken, shape ``(...)``, and its terms (for ``info``)."""
        raise NotImplementedError

    def terminated(self, q: np.ndarray, v: np.ndarray, now: Any, task: Any) -> np.ndarray:
        """Task failure besides divergence, bool ``(...)``."""
        return np.zeros(np.shape(q)[:-1], bool)

    def state_diverged(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Non-finite, absurdly large or singular states, or (constrained models) a constraint residual
        beyond ``residual_limit``, bool ``(...)`` (what the compiled step's engine checks)."""
        bad = diverged(q, v, self.divergence_limit, self.model)
        if self.model.nc and self.residual_limit < np.inf:
            with np.errstate(invalid="ignore"):
                bad = bad | ~(np.max(np.abs(self.model.constraint_residual(q)), axis=-1) <= self.residual_limit)
        return bad

    def constraint_info(self, q: np.ndarray, v: np.ndarray, u: np.ndarray) -> dict[str, Any]:
        """``info``'s entries of a constrained model (none without constraints): ``constraint_residual``
        (``max |phi|`` [m]) and the ``multipliers`` of the motion under ``u`` (by the compiled kernel when the
        step is compiled, as the engine reports them)."""
        if not self.model.nc:
            return {}
        return {
            "constraint_residual": np.max(np.abs(self.model.constraint_residual(q)), axis=-1),
            "multipliers": self.model.multipliers(q, v, u, compiled=self.compiled is not None),
        }

    def task_info(self, q: np.ndarray, v: np.ndarray, now: Any, task: Any, u: np.ndarray) -> dict[str, Any]:
        """Task quantities for ``info``, each shaped ``(...)`` or ``(..., k)``."""
        return {}

    def now(self) -> Any:
        """``task_now`` at the current time."""
        return self.task_now(np.asarray(self._t), self._task)

    #: reset option keys a task accepts besides ``q`` and ``v``.
    task_options: ClassVar[tuple[str, ...]] = ()

    # -- Gymnasium API -------------------------------------------------------

    def __init_subclass__(cls, **kwargs):
        """A scene's construction may call the package's kernels before they are compiled: as Python meanwhile
        (:func:`mbs_envs.dynamics.background.allowed`)."""
        super().__init_subclass__(**kwargs)
        if "__init__" in cls.__dict__:
            init = cls.__init__

            @functools.wraps(init)
            def __init__(self, *args, **kw):
                with background.allowed():
                    init(self, *args, **kw)

            cls.__init__ = __init__

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode.

        ``options={"q": q0, "v": v0}`` starts from an exact state (``v``
        defaults to zero when only ``q`` is given); otherwise the task's start
        distribution is sampled. ``seed``: None or an int ``>= 0``
        (:func:`mbs_envs.validation.seed`). A refused reset (``ValueError``) changes nothing: the start
        is drawn from a copy of the generator (or the new seed's), which replaces this env's only
        once the start is accepted.
        """
        with background.allowed():  # kernels not compiled yet run as Python meanwhile (mbs_envs.dynamics.background)
            return self._reset(seed=seed, options=options)

    def _reset(self, *, seed: int | None = None, options: dict | None = None):
        """:meth:`reset`'s work."""
        seed = check.seed(seed)
        options = self.check_reset_options(options)
        if seed is None:
            rng, rng_seed = copy.deepcopy(self.np_random), self.np_random_seed
        else:
            rng, rng_seed = seeding.np_random(seed)
        task, q0, v0 = self.sample_start(options, rng)  # may refuse the start: nothing has changed yet
        self._np_random, self._np_random_seed = rng, rng_seed  # what Env.reset(seed=...) sets
        self._t = 0.0
        self._u = np.zeros(self.model.nu)
        self._task = task
        self._q, self._v = np.array(q0, float), np.array(v0, float)  # private: steps may update them in place
        self._started = True
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info(diverged=False)

    def _require_reset(self, what: str) -> None:
        if not self.__dict__.get("_started", True):
            raise gym.error.ResetNeeded(f"call reset() before {what}() (the env has no state yet)")

    def check_reset_options(self, options: dict | None) -> dict:
        """Validate reset options (unknown keys, ``q``/``v`` shape and finiteness) before any change."""
        options = check.mapping(options, "options")
        unknown = sorted(set(options) - {"q", "v"} - set(self.task_options))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; known: {['q', 'v', *self.task_options]}")
        for key, n in (("q", self.model.nq), ("v", self.model.nv)):
            options[key] = self._checked_state(options, key, n)
        return options

    def sample_start(
        self, options: dict, rng: np.random.Generator | None = None, model: Model | None = None
    ) -> tuple[Any, np.ndarray, np.ndarray]:
        """Draw ``(task, q0, v0)`` from ``rng`` (default this env's ``np_random``) for ``model``
        (default this env's); checked ``options`` may fix the state. Nothing of the env changes."""
        task, q0, v0 = self.draw_start(options, rng, model)
        self._check_start(q0, v0, task, given=self.start_given(options))
        return task, q0, v0

    @staticmethod
    def start_given(options: dict) -> bool:
        """Whether checked reset ``options`` fix the start state (for the refusal's message)."""
        return options.get("q") is not None or options.get("v") is not None

    def draw_start(
        self, options: dict, rng: np.random.Generator | None = None, model: Model | None = None
    ) -> tuple[Any, np.ndarray, np.ndarray]:
        """:meth:`sample_start` without the check: member 0 of :meth:`draw_starts` with one generator."""
        task, q0, v0 = self.draw_starts(options, [self.np_random if rng is None else rng], model)
        return tree_pick(task, 0), q0[0], v0[0]

    def draw_starts(
        self, options: dict, rngs: list[np.random.Generator], model: Model | None = None
    ) -> tuple[Any, np.ndarray, np.ndarray]:
        """Draw ``(task, q0, v0)`` of ``L = len(rngs)`` members, member ``i``'s random numbers from
        ``rngs[i]`` (its task's first, then its state's: the same draws whatever ``L``), the rest
        computed for all members at once; unchecked (:meth:`_check_start`, which the vector env makes
        once for all the members it resets).

        Parameters
        ----------
        options : dict
            Checked reset options; ``q``, ``v`` fix every member's start.
        rngs : list of numpy.random.Generator
        model : Model, optional
            Default this env's; a vector env passes its members' parameters, shape ``(L,)``.

        Returns
        -------
        task : stacked task (``L`` members) or None
        q0 : ndarray, shape (L, nq)
        v0 : ndarray, shape (L, nv)
        """
        model = self.model if model is None else model
        L = len(rngs)
        task = self._draw_tasks(options, rngs)
        q0, v0 = options.get("q"), options.get("v")
        if q0 is None:
            q0, v_s = self._draw_states(task, rngs, model)
            v0 = v_s if v0 is None else np.broadcast_to(v0, (L, model.nv))
        else:
            q0 = np.broadcast_to(q0, (L, model.nq))
            v0 = np.zeros((L, model.nv)) if v0 is None else np.broadcast_to(v0, (L, model.nv))
        q0, v0 = model.make_consistent(q0, v0, self.consistency_tol)  # constrained scenes project (or refuse)
        return task, q0, v0

    def _check_start_bound(self, bound: float) -> None:
        """Refuse at construction a ``divergence_limit`` below ``bound``, an upper bound on
        the entries ``|q|, |v|`` of the task's start distribution (each episode would start diverged)."""
        if not bound <= self.divergence_limit:
            raise ValueError(
                f"divergence_limit = {self.divergence_limit:g} is below the start states of this task "
                f"(|q|, |v| entries up to {bound:.3g}); raise it"
            )

    def _check_start(self, q0: np.ndarray, v0: np.ndarray, task: Any, given: bool) -> np.ndarray:
        """Refuse a start state the episode cannot begin from: non-finite, beyond
        ``divergence_limit``, singular, or whose observation leaves ``observation_space``; else return
        that observation. Batched: ``q0 (..., nq)``, ``v0 (..., nv)`` with ``task`` stacked alike (the
        vector env's members checked at once; the message names the first refused).

        Raises
        ------
        ValueError
            Naming the state (given in ``options`` or sampled) and the limit.
        """
        source = "the start state given in options" if given else "a sampled start state"
        q0, v0 = np.asarray(q0), np.asarray(v0)
        bad = np.asarray(self.state_diverged(q0, v0), bool)
        if bad.any():
            i = np.unravel_index(np.argmax(bad), bad.shape) if bad.ndim else ()
            raise ValueError(
                f"{source} (q = {q0[i].tolist()}, v = {v0[i].tolist()}) is not finite, "
                f"singular, or beyond divergence_limit = {self.divergence_limit:g}"
                + ("" if given else "; raise divergence_limit")
            )
        with np.errstate(all="ignore"):
            obs = self.observe(q0, v0, self.task_now(np.zeros(q0.shape[:-1]), task), task)
        space = self.observation_space
        inside = np.all(
            np.isfinite(obs) & (obs >= space.low) & (obs <= space.high), axis=-1
        )  # Box.contains, per member
        if not np.all(inside):
            i = np.unravel_index(np.argmin(inside), inside.shape) if np.ndim(inside) else ()
            raise ValueError(
                f"{source} (q = {q0[i].tolist()}, v = {v0[i].tolist()}) gives an observation "
                f"outside observation_space: {np.asarray(obs)[i].tolist()}"
            )
        return obs

    @staticmethod
    def _checked_state(options: dict, key: str, n: int) -> np.ndarray | None:
        if key not in options or options[key] is None:
            return None
        x = as_vector(options[key], n, f"options[{key!r}]")
        if x.shape != (n,) or not np.all(np.isfinite(x)):
            raise ValueError(f"options[{key!r}] must be a finite array of shape ({n},)")
        return x.copy()

    #: largest constraint residual [m] a start state may keep after projection
    consistency_tol: ClassVar[float] = 1e-9

    def step(self, action: Any):
        if self.__dict__.get("_warm"):  # its kernels compiled
            return self._step(action)
        with background.allowed():  # kernels not compiled yet run as Python meanwhile (mbs_envs.dynamics.background)
            out = self._step(action)
        self._warm = self.dispatch.warm
        return out

    def _step(self, action: Any):
        self._require_reset("step")
        d = self.dispatch
        tab = d.tableau()
        if tab is not None:
            return self._step_compiled(action, tab, d)
        action = validate_action(action, self.model.nu)  # raises before any change
        q, v, t, u, obs, reward, terminated, bad, info_rows = self.step_rows(
            self.model, self._q[None], self._v[None], np.array([self._t]), self._task, action[None]
        )
        self._q, self._v, self._t, self._u = q[0], v[0], float(t[0]), u[0]
        return self._single_step_result(obs, reward, terminated, bad, {k: _scalar(x[0]) for k, x in info_rows.items()})

    def step_rows(self, model: Model, q, v, t, task: Any, action, full_info: bool = True) -> tuple:
        """The numpy control step of a batch of rows (a single env: one row): the same sequence
        as the compiled one (:mod:`mbs_envs.envs.engine`), through the task's batched functions.

        Parameters
        ----------
        model : Model
            The rows' model (per-member parameters allowed).
        q, v : ndarray, shape (B, n)
        t : ndarray, shape (B,)
        task : Any
            The rows' task (one episode's, or stacked per member).
        action : ndarray, shape (B, nu)
            Validated and clipped.
        full_info : bool
            Whether ``info`` is computed (else empty).

        Returns
        -------
        q, v, t, u : ndarray
            The new state (a diverged row keeps its own) and the applied input.
        obs : ndarray, float32, shape (B, obs_dim)
        reward : ndarray, shape (B,)
        terminated, bad : ndarray of bool, shape (B,)
        info : dict
            ``energy``, the reward terms and the task's quantities, one row per member.
        """
        u = action * self.u_max
        q1, v1 = advance(
            model, self.integrator, 0.0, q, v, self.dt, self.substeps, u, self.stabilization, compiled=False
        )
        bad = np.asarray(self.state_diverged(q1, v1), bool)
        q, v = np.where(bad[:, None], q, q1), np.where(bad[:, None], v, v1)  # a diverged row keeps its state
        t = t + self.dt
        now = self.task_now(t, task)
        reward, terms = self.reward(q, v, now, task, u, action)
        terminated = bad | self.terminated(q, v, now, task)
        info: dict[str, Any] = {}
        if full_info:
            info = {"energy": model.energy(q, v), **terms, **self.task_info(q, v, now, task, u)}
        return q, v, t, u, self.observe(q, v, now, task), np.asarray(reward, float), terminated, bad, info

    def _observation(self) -> np.ndarray:
        return self.observe(self._q, self._v, self.now(), self._task)

    def _info(self, diverged: bool, now: Any = None) -> dict[str, Any]:
        now = self.now() if now is None else now
        info = {"t": self._t, "energy": float(self.model.energy(self._q, self._v)), "diverged": diverged}
        task = self.task_info(self._q, self._v, now, self._task, self._u)
        info.update({k: _scalar(x) for k, x in task.items()})
        return info

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_renderer"] = None  # a pygame window is not picklable; reopened on demand
        state.pop("_dispatch", None)  # nor a compiled entry point: the dispatch is built again
        state.pop("_warm", None)
        return state
