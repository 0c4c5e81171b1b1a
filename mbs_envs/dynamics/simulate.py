"""Simulation of a model independent of Gymnasium: ``simulate(model, ...)``.

:func:`advance` is the one place where a model, an input and an integrator meet;
:func:`simulate` and the environments both go through it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from . import integrators
from .. import validation as check
from .compiled import advance_compiled, compiled_stepping
from .inputs import JointPD
from .integrators import Acceleration, JointImplicitEuler, ScipyIVP, Stepper
from ..validation import as_vector

if TYPE_CHECKING:
    from ..models.base import Model

#: Input: None (zero), an array ``(..., nu)`` held constant, ``u(t, q, v)``, or a
#: :class:`~mbs_envs.dynamics.inputs.JointPD` (a callable whose gains the implicit joint step uses).
Input = None | np.ndarray | Callable[[float, np.ndarray, np.ndarray], np.ndarray]

#: Default bound on ``|q|`` and ``|v|`` beyond which a state counts as diverged.
DIVERGENCE_LIMIT = 1e8


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """A simulated motion.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Times [s], ``t[0] = 0``.
    q : ndarray, shape (K, ..., nq)
    v : ndarray, shape (K, ..., nv)
    diverged : ndarray of bool, shape (...)
        Which members of the batch diverged. With a fixed-step method a
        diverged member is held at its last finite state from then on; with an
        adaptive one (a single solve for the whole batch) the trajectory ends at
        the last finite output and every member is flagged.
    integrator : str
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    diverged: np.ndarray
    integrator: str


def _read_only(x: Any) -> Any:
    """A read-only view of the array ``x`` (anything else as it is)."""
    if not isinstance(x, np.ndarray):
        return x
    view = x.view()
    view.flags.writeable = False
    return view


def input_function(model: Model, u: Input) -> Callable[[float, np.ndarray, np.ndarray], Any]:
    """Normalize an input specification to a function ``u(t, q, v)``.

    A user's callable gets read-only views of the integrator's state arrays (numpy refuses a write into them).

    Raises
    ------
    ValueError
        If an array input has the wrong trailing shape or is not finite.
    """
    if isinstance(u, JointPD):
        B = model.actuation
        return lambda t, q, v: u(t, q, v, B)
    if u is None:
        return lambda t, q, v: None
    if callable(u):  # the user's function sees read-only views: writing into them cannot change the motion
        return lambda t, q, v: u(t, _read_only(q), _read_only(v))
    u_arr = as_vector(u, model.nu, "u")
    if not np.all(np.isfinite(u_arr)):
        raise ValueError("u must be finite")
    return lambda t, q, v: u_arr


def acceleration(model: Model, u: Input, stabilization: Any = None) -> Acceleration:
    """The right-hand side ``a(t, q, v) = forward_dynamics(q, v, u(t, q, v))``.

    With a ``stabilization`` (constrained models), its Baumgarte terms are included.
    """
    u_fn = input_function(model, u)
    if stabilization is None:
        return lambda t, q, v: model.forward_dynamics(q, v, u_fn(t, q, v))
    return lambda t, q, v: model.accelerations(q, v, u_fn(t, q, v), stabilization)


def diverged(q: np.ndarray, v: np.ndarray, limit: float = DIVERGENCE_LIMIT, model: Model | None = None) -> np.ndarray:
    """Whether states stopped being finite, left ``|x| <= limit``, or reached a
    singularity of the model's coordinates (``model.singular``).

    Parameters
    ----------
    q : ndarray, shape (..., nq)
    v : ndarray, shape (..., nv)
    limit : float
    model : Model, optional

    Returns
    -------
    ndarray of bool, shape (...)
    """
    with np.errstate(invalid="ignore"):
        ok_q = np.all(np.abs(q) <= limit, axis=-1)  # False for NaN
        ok_v = np.all(np.abs(v) <= limit, axis=-1)
        bad = ~(ok_q & ok_v)
        if model is not None:
            bad = bad | model.singular(np.where(np.isfinite(q), q, 0.0))
    return bad


def advance(
    model: Model,
    stepper: Stepper,
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    duration: float,
    substeps: int = 1,
    u: Input = None,
    stabilization: Any = None,
    compiled: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate from ``t`` over ``duration``.

    Fixed-step methods take ``substeps`` equal steps; adaptive methods make one
    solve over the interval (``substeps`` is ignored). Floating-point warnings
    are silenced here: a blow-up (including a mass matrix that stops being
    positive definite on garbage states) shows up as non-finite values that
    the caller detects with :func:`diverged`. ``stabilization`` (from
    ``model.stabilization(...)``, None for unconstrained models) adds Baumgarte
    terms to the dynamics or projects the state after every step.

    With ``compiled`` (default), a held input (None or an array, not a callable)
    and a model and method the compiled kernels cover
    (:func:`mbs_envs.dynamics.compiled.compiled_stepping`), the steps run compiled: the
    same stages, equal to the numpy path to rounding (1e-12, tested).

    Returns
    -------
    q, v : ndarray
        The state at ``t + duration``.
    """
    tab = compiled_stepping(model, stepper, stabilization) if compiled and not callable(u) else None
    if tab is not None:
        u_held = input_function(model, u)(t, q, v)
        with np.errstate(all="ignore"):
            u_held = np.zeros(model.nu) if u_held is None else u_held
            return advance_compiled(model, tab, q, v, u_held, duration, substeps, stabilization)
    acc = acceleration(model, u, stabilization)
    steps = 1 if isinstance(stepper, ScipyIVP) else substeps
    h = duration / steps
    step = stepper.step
    if isinstance(stepper, JointImplicitEuler):  # steps the model itself (its mass matrix's diagonal)
        stepper.check_model(model)
        u_fn, law = input_function(model, u), (u if isinstance(u, JointPD) else None)
        step = lambda acc, t, q, v, h: stepper.step_model(model, u_fn, law, t, q, v, h)  # noqa: E731
    try:
        with np.errstate(all="ignore"):
            for k in range(steps):
                q, v = step(acc, t + k * h, q, v, h)
                if stabilization is not None:
                    q, v = model.after_step(q, v, stabilization)
    except np.linalg.LinAlgError:  # M(q) stopped being positive definite: a blow-up
        q = np.full(np.shape(q), np.nan)
        v = np.full(np.shape(v), np.nan)
    return q, v


#: The most state values (output samples x members x (nq + nv)) :func:`simulate` stores: 2^28 float64
#: entries, 2 GiB (a 2R over 1e7 steps of one member is 4e7, the studies' largest runs far less).
MAX_STORED_VALUES = 2**28


def simulate(
    model: Model,
    q0: np.ndarray,
    v0: np.ndarray,
    t_final: float,
    dt: float = 1e-3,
    integrator: Any = "rk4",
    u: Input = None,
    *,
    stabilization: Any = None,
    divergence_limit: float = DIVERGENCE_LIMIT,
    compiled: bool = True,
    **integrator_options: Any,
) -> Trajectory:
    """Simulate ``model`` from ``(q0, v0)`` over ``[0, t_final]``.

    Parameters
    ----------
    model : Model
    q0 : array_like, shape (..., nq)
    v0 : array_like, shape (..., nv)
        Initial state; leading dimensions form a batch.
    t_final : float
        End time [s], > 0.
    dt : float
        Step [s] of the output grid ``0, dt, 2 dt, ..., t_final`` (the last
        interval may be shorter); the step size of fixed-step methods.
    integrator : str or stepper
        A name from :func:`mbs_envs.dynamics.integrators.available`, or a ready stepper
        (e.g. one whose ``counters`` a report reads afterwards).
    u : None, array_like (..., nu), or callable ``u(t, q, v)``
        The input; a callable is evaluated at every stage (continuous control).
    stabilization : {None, "projection", "baumgarte", "none"} or Stabilization
        Constrained models only (default projection); see
        :class:`mbs_envs.dynamics.constraints.Stabilization`. With an adaptive
        integrator the projection is applied once per output interval.
    divergence_limit : float
        Bound on ``|q|, |v|`` (see :func:`diverged`).
    compiled : bool
        Take the compiled kernels where they apply (see :func:`advance`);
        False forces the numpy path.
    **integrator_options
        ``rtol``, ``atol`` for the adaptive methods.

    Returns
    -------
    Trajectory

    Raises
    ------
    ValueError
        For a non-positive or non-finite ``t_final``/``dt``/``divergence_limit``,
        badly shaped or non-finite initial states, an initial state already
        beyond ``divergence_limit`` (or singular), or an unknown integrator.
    """
    t_final = check.positive(t_final, "t_final")
    dt = check.positive(dt, "dt")
    divergence_limit = check.positive(divergence_limit, "divergence_limit")
    q0 = as_vector(q0, model.nq, "q0")
    v0 = as_vector(v0, model.nv, "v0")
    if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(v0))):
        raise ValueError("q0 and v0 must be finite")
    batch = np.broadcast_shapes(q0.shape[:-1], v0.shape[:-1])
    q0 = np.broadcast_to(q0, batch + (model.nq,)).copy()
    v0 = np.broadcast_to(v0, batch + (model.nv,)).copy()
    start_bad = diverged(q0, v0, divergence_limit, model)
    if np.any(start_bad):
        raise ValueError(
            f"the initial state is beyond divergence_limit = {divergence_limit:g} or singular "
            f"(members {np.flatnonzero(start_bad.reshape(-1)).tolist()} of the batch)"
        )
    values = (t_final / dt + 2.0) * max(1, int(np.prod(batch))) * (model.nq + model.nv)
    if not values <= MAX_STORED_VALUES:  # also refuses t_final / dt = inf (1e300 / 1e-300)
        raise ValueError(
            f"t_final / dt = {t_final:g} / {dt:g} steps of {int(np.prod(batch))} member(s) would store {values:.3g} state "
            f"values, above the budget of {MAX_STORED_VALUES:.3g} ({MAX_STORED_VALUES * 8 / 2**30:g} GiB; "
            "mbs_envs.dynamics.simulate.MAX_STORED_VALUES): a larger dt, a shorter t_final or a smaller batch"
        )
    stepper = integrators.get(integrator, **integrator_options)
    stab = model.stabilization(stabilization)
    n_steps = max(1, int(np.ceil(t_final / dt - 1e-9)))
    t = np.minimum(np.arange(n_steps + 1) * dt, t_final)
    t[-1] = t_final

    if isinstance(stepper, ScipyIVP) and stab is None:
        acc = acceleration(model, u)
        ts, qs, vs, _ = stepper.solve(acc, 0.0, q0, v0, t[1:])
        qs = np.concatenate([q0[None], qs])
        vs = np.concatenate([v0[None], vs])
        bad = diverged(qs, vs, divergence_limit, model)
        first_bad = np.argmax(bad.reshape(len(qs), -1).any(axis=1)) if bad.any() else None
        if first_bad is not None or len(ts) < len(t) - 1:
            K = first_bad if first_bad is not None else len(qs)
            return Trajectory(t[:K], qs[:K], vs[:K], np.ones(batch, bool), stepper.name)
        return Trajectory(t, qs, vs, np.zeros(batch, bool), stepper.name)

    qs = np.empty((n_steps + 1,) + q0.shape)
    vs = np.empty((n_steps + 1,) + v0.shape)
    qs[0], vs[0] = q0, v0
    gone = np.zeros(batch, bool)
    q, v = q0, v0
    for k in range(n_steps):
        q_new, v_new = advance(model, stepper, t[k], q, v, t[k + 1] - t[k], 1, u, stab, compiled)
        bad = diverged(q_new, v_new, divergence_limit, model)
        if bad.any():
            gone |= bad
            q_new = np.where(bad[..., None], q, q_new)  # hold the last finite state
            v_new = np.where(bad[..., None], v, v_new)
        qs[k + 1], vs[k + 1] = q_new, v_new
        q, v = q_new, v_new
    return Trajectory(t, qs, vs, gone, stepper.name)
