"""The stiff-case scans' runs and scores (``scripts/stiff_cases.py``); the work-precision
protocol is :mod:`mbs_envs.studies.work_precision`.

A :class:`Case` is a model, a start state, an input and a horizon. One run of
one integrator at one setting (a step ``dt`` for fixed-step methods, a
tolerance ``rtol`` for adaptive ones) is scored by :func:`score` against a
reference solution computed once per case by a different, high-accuracy
method (:func:`reference`):

- ``state_error``: ``max(|q(T) - q_ref(T)|, |v(T) - v_ref(T)|)`` (max norm) [rad, rad/s, m];
- ``trajectory_error``: the same, maximum over the grid ``0, 0.05, 0.1, ...`` s (:data:`GRID`);
- ``halvings`` (implicit fixed-step methods: steps split because Newton failed), ``steps`` and
  ``evaluations`` (adaptive: accepted steps and right-hand sides);
- ``energy_error``: ``max_t |E(t) - E(0)|`` [J], for cases without input or
  friction (where energy is a conserved quantity), else NaN;
- ``constraint_error``: ``max_t max(|phi(q)|, |Psi(q) v|)`` for constrained
  models (the position and velocity residuals), else NaN;
- ``cpu_s``: process CPU time of the run (``time.process_time``), and
  ``wall_s``.
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from ..dynamics import integrators
from ..models.base import Model
from ..dynamics.simulate import Input, simulate

if TYPE_CHECKING:
    from ..envs.references import SumOfSines

FIXED = ("euler", "semi_implicit_euler", "midpoint", "rk4", "implicit_euler", "sdirk2", "sdirk3")
ADAPTIVE = ("rk45", "dop853", "radau", "bdf", "lsoda")


@dataclasses.dataclass(frozen=True)
class Case:
    """A simulation to measure.

    Attributes
    ----------
    scene : str
        Name used in tables and file names.
    model : Model
    q0, v0 : ndarray
        Start state (consistent with the constraints of a constrained model).
    t_final : float
        Horizon [s].
    u : None, ndarray or callable ``u(t, q, v)``
        Input (None: free motion).
    stabilization : str, optional
        Constrained models: ``"projection"``, ``"baumgarte"`` or ``"none"``.
    dt_out : float
        Output grid of adaptive runs (energy and constraint errors are
        taken on it) [s].
    conservative : bool
        Whether the energy is conserved (no input, no friction).
    reference_method : str
        ``"dop853"`` (non-stiff) or ``"radau"`` (stiff) for the reference.
    """

    scene: str
    model: Model
    q0: np.ndarray
    v0: np.ndarray
    t_final: float
    u: Input = None
    stabilization: Any = None
    dt_out: float = 0.01
    conservative: bool = True
    reference_method: str = "dop853"


@dataclasses.dataclass(frozen=True)
class Reference:
    """The reference final state and an estimate of its own error.

    ``error_estimate`` is the difference between the reference and the same
    method at a 100x looser tolerance: an upper bound for the reference's error
    when the method converges.
    """

    q: np.ndarray
    v: np.ndarray
    error_estimate: float
    method: str
    rtol: float
    Q: np.ndarray | None = None  # the states on the GRID points (trajectory errors)
    V: np.ndarray | None = None


def reference(case: Case, rtol: float = 1e-12) -> Reference:
    """High-accuracy solution of ``case`` (no stabilization: the exact index-1 ODE): one solve, output
    every ``case.dt_out`` (the evaluation budget of the solve is per output interval); kept at its
    final time and on the :data:`GRID` points, with its error estimate over those points."""
    runs = []
    for tol in (rtol, 100 * rtol):
        tr = simulate(
            case.model, case.q0, case.v0, case.t_final, dt=case.dt_out, integrator=case.reference_method,
            u=case.u, stabilization="none", rtol=tol, atol=tol,
        )  # fmt: skip
        if bool(np.any(tr.diverged)):
            raise RuntimeError(f"reference solution of {case.scene} failed")
        runs.append(on_grid(tr))
    (Q, V), (Q2, V2) = runs
    est = state_difference(Q, V, Q2, V2)
    return Reference(Q[-1], V[-1], est, case.reference_method, rtol, Q, V)


#: [s] the grid on which trajectory errors are taken: every run's output lands on it (fixed steps
#: ``0.05 * 2^-k``, adaptive runs every ``dt_out = 0.01``)
GRID = 0.05


def on_grid(tr: Any) -> tuple[np.ndarray, np.ndarray]:
    """The states of a trajectory at the multiples of :data:`GRID` (and its final time)."""
    k = np.round(tr.t / GRID)
    keep = np.isclose(tr.t, k * GRID, rtol=0, atol=1e-9) | (np.arange(len(tr.t)) == len(tr.t) - 1)
    return tr.q[keep], tr.v[keep]


def state_difference(Q: np.ndarray, V: np.ndarray, Q2: np.ndarray, V2: np.ndarray) -> float:
    """``max(|Q - Q2|, |V - V2|)`` over every entry (max norm of the state, over all samples given)."""
    return float(max(np.max(np.abs(Q - Q2)), np.max(np.abs(V - V2))))


def trajectory_error(tr: Any, ref: Reference) -> float:
    """:func:`state_difference` of a trajectory and the reference on the :data:`GRID` points; inf where
    the trajectory does not cover them (it stopped early)."""
    Q, V = on_grid(tr)
    return state_difference(Q, V, ref.Q, ref.V) if Q.shape == ref.Q.shape else float("inf")


def constraint_error(model: Model, q: np.ndarray, v: np.ndarray) -> float:
    """``max(|phi(q)|, |Psi(q) v|)`` over all samples, NaN for unconstrained models."""
    if model.nc == 0:
        return float("nan")
    return float(np.max(model.constraint_violation(q, v)))


def score(case: Case, ref: Reference, integrator: str, setting: float) -> dict[str, Any]:
    """Run ``case`` with one integrator at one setting and measure it (see the module docstring).

    Parameters
    ----------
    setting : float
        ``dt`` [s] for fixed-step methods, ``rtol`` for adaptive ones (``atol = rtol``).

    Returns
    -------
    dict
        One CSV row: ``scene, integrator, kind, setting_name, setting,
        state_error, energy_error, constraint_error, cpu_s, wall_s, steps, diverged``.
    """
    adaptive = integrators.get(integrator).adaptive
    stepper = integrators.get(integrator, **({"rtol": setting, "atol": setting} if adaptive else {}))
    dt = case.dt_out if adaptive else setting
    c0, w0 = time.process_time(), time.perf_counter()
    tr = simulate(  # the numpy path for every method: the CPU times compare methods, not implementations
        case.model, case.q0, case.v0, case.t_final, dt=dt, integrator=stepper, u=case.u,
        stabilization=case.stabilization, compiled=False,
    )  # fmt: skip
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    diverged = bool(np.any(tr.diverged)) or not np.isclose(tr.t[-1], case.t_final)
    row = {
        "scene": case.scene,
        "integrator": integrator,
        "kind": "adaptive" if adaptive else "fixed",
        "setting_name": "rtol" if adaptive else "dt",
        "setting": setting,
        "state_error": float("inf"),
        "trajectory_error": float("inf"),
        "energy_error": float("nan"),
        "constraint_error": float("nan"),
        "cpu_s": cpu,
        "wall_s": wall,
        "steps": stepper.counters.get("steps") if adaptive else len(tr.t) - 1,
        "halvings": stepper.counters.get("halvings", 0) if hasattr(stepper, "counters") and not adaptive else None,
        "evaluations": stepper.counters.get("evaluations") if adaptive else None,
        "diverged": diverged,
    }
    if diverged:
        return row
    row["state_error"] = state_difference(tr.q[-1], tr.v[-1], ref.q, ref.v)
    row["trajectory_error"] = trajectory_error(tr, ref)
    if case.conservative:
        E = case.model.energy(tr.q, tr.v)
        row["energy_error"] = float(np.max(np.abs(E - E[0])))
    row["constraint_error"] = constraint_error(case.model, tr.q, tr.v)
    return row


def fixed_steps(coarsest: float, n: int) -> list[float]:
    """``coarsest * 2^-k`` for ``k = 0 .. n-1`` [s]."""
    return [coarsest * 2.0**-k for k in range(n)]


def pd_law(kp: float, kd: float, q_star: np.ndarray):
    """``u = kp (q* - q) - kd v``: a high-gain regulator (continuous in time)."""
    return lambda t, q, v: kp * (q_star - q) - kd * v


def computed_torque_law(model: Model, reference: SumOfSines, kp: float, kd: float):
    """``u = inverse_dynamics(q, v, a_ref + kd (v_ref - v) + kp (q_ref - q))`` (continuous)."""

    def u(t, q, v):
        q_ref, v_ref, a_ref = reference(t)
        return model.inverse_dynamics(q, v, a_ref + kd * (v_ref - v) + kp * (q_ref - q))

    return u
