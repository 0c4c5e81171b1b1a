"""Work-precision, measured as DiffEqDevTools' ``WorkPrecisionSet`` does: error against run time.

A :class:`Problem` is a model, a start state, a horizon cut into intervals, and
an input held over each interval (or none). Two kinds per scene:

- ``free``: no input, no friction (energy is conserved), intervals of 0.04 s;
- ``forced``: the scene as its environment runs it (``gym.make`` with the
  registry's keywords): its model with its default friction, its start state
  (``reset(seed=0)``), and a smooth torque (a seeded sum of sines at 30 % of the
  torque limit) held over each control step (the environment's ``dt``).

Every run of one method at one setting is

- **timed** by :func:`timed`: a warm-up run (it compiles kernels), then the
  median and the minimum of ``repeats`` runs of the stepping loop alone
  (``time.perf_counter``; the problem is built beforehand). Fixed-step methods
  run as environments do: one :func:`~mbs_envs.dynamics.simulate.advance` per
  interval with ``interval / dt`` substeps, on the numpy path and, where it
  applies, the compiled path. Adaptive methods make **one whole-trajectory
  solve** of free problems (unstabilized for constrained models: their
  drift is the constraint residual) and, on forced problems, a solve per
  interval, **restarted** at every input change as an environment does
  (``kind = "adaptive, restarted"``);
- **counted**: right-hand-side evaluations per member (a Jacobian of ``2 n``
  perturbed states counts ``2 n``), by a separate numpy-path run;
- **scored** against a verified reference (:func:`reference`): DOP853 and Radau
  IIA at ``rtol = atol = 1e-13`` on the unstabilized equations (restarted per
  interval where the input changes); the reference is DOP853's, and the largest
  difference of the two over the grid is the **floor** (no error below it can be
  resolved). Error measures over the output grid ``0, interval, 2 interval, ...``:
  ``final_error`` (max norm of ``(q, v)`` at the end), ``trajectory_error`` (its
  maximum over the grid), ``energy_drift`` ``max |E - E(0)|`` (free problems),
  ``constraint_residual`` ``max(|phi|, |Psi v|)`` (constrained models).
"""

from __future__ import annotations

import copy
import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..dynamics import integrators
from ..dynamics.simulate import acceleration, advance, diverged
from ..models.base import Model
from .numerics import state_difference

#: fixed-step methods of the set (the joint-implicit one on unconstrained models)
FIXED = (
    "euler",
    "semi_implicit_euler",
    "midpoint",
    "rk4",
    "implicit_euler",
    "sdirk2",
    "sdirk3",
    "joint_implicit_euler",
)
#: adaptive methods (scipy's), swept over ``rtol = atol``
ADAPTIVE = ("rk45", "dop853", "radau", "bdf", "lsoda")
#: tolerance of the two reference solutions
REFERENCE_TOL = 1e-13


@dataclasses.dataclass(frozen=True)
class Problem:
    """One motion to measure (see the module docstring).

    Attributes
    ----------
    scene, kind : str
        ``kind`` is ``"free"`` or ``"forced"``.
    model : Model
    q0, v0 : ndarray
        Start state (consistent with a constrained model's constraints).
    interval : float
        Output grid step and input hold [s].
    steps : int
        Number of intervals (horizon ``steps * interval``).
    u : ndarray, shape (steps, nu), or None
        Input held over each interval.
    stabilization : str or None
        Constrained models: what the fixed-step runs use (``"projection"``, the environments').
    """

    scene: str
    kind: str
    model: Model
    q0: np.ndarray
    v0: np.ndarray
    interval: float
    steps: int
    u: np.ndarray | None = None
    stabilization: str | None = None

    @property
    def name(self) -> str:
        return f"{self.scene}-{self.kind}"

    @property
    def t_final(self) -> float:
        return self.steps * self.interval

    @property
    def conservative(self) -> bool:
        return self.u is None and self.kind == "free"


def smooth_torque(u_max: np.ndarray, times: np.ndarray, seed: int = 0) -> np.ndarray:
    """``u_j(t) = 0.3 u_max,j (sin(w1 t + p1) + sin(w2 t + p2)) / 2`` at ``times``, shape ``(K, nu)``;
    frequencies ``U(0.5, 3)`` rad/s and phases ``U(0, 2 pi)`` drawn from ``seed``."""
    u_max = np.asarray(u_max, float)
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.5, 3.0, (2, u_max.size))
    p = rng.uniform(0.0, 2 * np.pi, (2, u_max.size))
    t = np.asarray(times, float)[:, None]
    return 0.3 * u_max * 0.5 * (np.sin(w[0] * t + p[0]) + np.sin(w[1] * t + p[1]))


def free_problems(t_final: float = 1.0) -> list[Problem]:
    """Free motion of each model (the 2R and chains from a bent posture, the four-bar turning its
    crank, the disk rolling above its critical spin with a small lean), as each scene's registry
    entry declares it (:attr:`mbs_envs.envs.registry.Scene.free_motions`); output every 0.04 s."""
    from ..envs import registry

    steps = int(round(t_final / 0.04))
    return [
        Problem(label, "free", model, np.asarray(q0, float), np.asarray(v0, float), 0.04, steps, stabilization=stab)
        for s in registry.SCENES if s.free_motions
        for label, model, q0, v0, stab in registry.load(s.free_motions)()
    ]  # fmt: skip


def forced_problems(t_final: float = 1.0) -> list[Problem]:
    """Each registered scene as its environment runs it (module docstring), from the registry."""
    import gymnasium as gym

    from ..envs import registry

    out = []
    for s in registry.SCENES:
        env = gym.make(s.id, **dict(s.kwargs)).unwrapped
        env.reset(seed=0)
        steps = int(round(t_final / env.dt))
        u = smooth_torque(env.u_max, np.arange(steps) * env.dt)
        kind = getattr(env.stabilization, "kind", None)
        out.append(Problem(s.name.lower(), "forced", env.model, env._q.copy(), env._v.copy(), env.dt, steps, u, kind))
        env.close()
    return out


# -- running ---------------------------------------------------------------------------------


def solve(
    p: Problem, method: str, setting: float, compiled: bool = False, model: Model | None = None
) -> tuple[np.ndarray, np.ndarray, bool]:
    """One run: states on the output grid, shape ``(steps + 1, n)`` each, and whether it finished.

    ``setting`` is ``dt`` for fixed-step methods (``interval / dt`` substeps per
    interval), ``rtol = atol`` for adaptive ones (one solve of a free problem;
    one per interval, restarted, with an input). A diverged run stops there (the
    rest of the grid is NaN).
    """
    model = p.model if model is None else model
    adaptive = method in ADAPTIVE
    stepper = integrators.get(method, **({"rtol": setting, "atol": setting} if adaptive else {}))
    Q = np.full((p.steps + 1, p.q0.size), np.nan)
    V = np.full((p.steps + 1, p.v0.size), np.nan)
    Q[0], V[0] = p.q0, p.v0
    if adaptive and p.u is None:  # one whole-trajectory solve (no stabilization: a single ODE)
        acc = acceleration(model, None, model.stabilization("none") if model.nc else None)
        grid = np.arange(1, p.steps + 1) * p.interval
        ts, qs, vs, ok = stepper.solve(acc, 0.0, p.q0, p.v0, grid)
        Q[1 : 1 + len(ts)], V[1 : 1 + len(ts)] = qs, vs
        return Q, V, bool(ok) and not bool(np.any(diverged(Q, V, model=model)))
    substeps = 1 if adaptive else int(round(p.interval / setting))
    stab = model.stabilization(p.stabilization)
    q, v = p.q0, p.v0
    for k in range(p.steps):
        u = None if p.u is None else p.u[k]
        q, v = advance(model, stepper, k * p.interval, q, v, p.interval, substeps, u, stab, compiled)
        if np.any(diverged(q, v, model=model)):
            return Q, V, False
        Q[k + 1], V[k + 1] = q, v
    return Q, V, True


def counting(model: Model) -> tuple[Model, list[int]]:
    """A copy of ``model`` that counts its right-hand-side evaluations per member.

    Counted: the outermost call of ``forward_dynamics``, ``accelerations`` or
    ``shifted_forward_dynamics`` (a call made inside another is not), each
    member of a batched call once.
    """
    calls = [0, 0]  # evaluations, depth
    base = type(model)

    def wrap(name: str) -> Callable:
        method = getattr(base, name)

        def counted(self, q, *args, **kwargs):
            if calls[1] == 0:
                calls[0] += max(1, int(np.size(q) // self.nq))
            calls[1] += 1
            try:
                return method(self, q, *args, **kwargs)
            finally:
                calls[1] -= 1

        return counted

    names = [n for n in ("forward_dynamics", "accelerations", "shifted_forward_dynamics") if hasattr(base, n)]
    Counting = type(f"Counting{base.__name__}", (base,), {n: wrap(n) for n in names})
    twin = copy.copy(model)
    twin.__class__ = Counting
    return twin, calls


def timed(fn: Callable[[], Any], repeats: int = 5) -> tuple[float, float, float]:
    """``(median, min, max)`` wall time [s] of ``repeats`` calls of ``fn`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), float(np.max(times))


@dataclasses.dataclass(frozen=True)
class Reference:
    """The reference states on the grid (DOP853's) and the floor: their largest difference from Radau's."""

    q: np.ndarray
    v: np.ndarray
    floor: float
    seconds: float


def reference(p: Problem) -> Reference:
    """DOP853 and Radau IIA at :data:`REFERENCE_TOL` on the unstabilized equations (module docstring)."""
    ref_p = dataclasses.replace(p, stabilization="none" if p.model.nc else None)
    t0 = time.perf_counter()
    runs = []
    for method in ("dop853", "radau"):
        Q, V, ok = solve(ref_p, method, REFERENCE_TOL)
        if not ok:
            raise RuntimeError(f"reference solution ({method}) of {p.name} failed")
        runs.append((Q, V))
    (Qa, Va), (Qb, Vb) = runs
    floor = state_difference(Qa, Va, Qb, Vb)
    return Reference(Qa, Va, floor, time.perf_counter() - t0)


def errors(p: Problem, ref: Reference, Q: np.ndarray, V: np.ndarray) -> dict[str, float]:
    """``final_error, trajectory_error, energy_drift, constraint_residual`` (module docstring; NaN where not defined)."""
    out = {
        "final_error": state_difference(Q[-1], V[-1], ref.q[-1], ref.v[-1]),
        "trajectory_error": state_difference(Q, V, ref.q, ref.v),
    }
    if p.conservative:
        E = p.model.energy(Q, V)
        out["energy_drift"] = float(np.max(np.abs(E - E[0])))
    else:
        out["energy_drift"] = float("nan")
    out["constraint_residual"] = float(np.max(p.model.constraint_violation(Q, V))) if p.model.nc else float("nan")
    return out


def applies(p: Problem, method: str) -> bool:
    """Whether ``method`` can run ``p`` (the joint-implicit step: unconstrained models)."""
    return integrators.applies(method, p.model)


def paths(p: Problem, method: str) -> tuple[bool, ...]:
    """``(False,)`` or ``(False, True)``: the numpy path, and the compiled one where the environment would take it."""
    from ..dynamics.compiled import compiled_stepping

    if method in ADAPTIVE:
        return (False,)
    stab = p.model.stabilization(p.stabilization)
    return (False, True) if compiled_stepping(p.model, integrators.get(method), stab) is not None else (False,)


def measure(p: Problem, ref: Reference, method: str, setting: float, repeats: int = 5) -> list[dict[str, Any]]:
    """Rows for one method at one setting: one per path (numpy, compiled), timed, counted and scored."""
    adaptive = method in ADAPTIVE
    twin, calls = counting(p.model)
    Q, V, ok = solve(p, method, setting, compiled=False, model=twin)
    rows = []
    for compiled in paths(p, method):
        row = {
            "problem": p.name, "scene": p.scene, "kind_of_problem": p.kind, "integrator": method,
            "kind": ("adaptive, restarted" if p.u is not None else "adaptive, one solve") if adaptive else "fixed",
            "setting_name": "rtol" if adaptive else "dt", "setting": setting,
            "path": "compiled" if compiled else "numpy", "rhs_evaluations": calls[0], "finished": ok,
            "reference_floor": ref.floor,
        }  # fmt: skip
        Qr, Vr = Q, V
        if compiled:  # the same stages: equal to rounding (its difference from the numpy path is recorded)
            Qr, Vr, row["finished"] = solve(p, method, setting, compiled=True)
            if ok and row["finished"]:
                row["compiled_minus_numpy"] = float(max(np.max(np.abs(Qr - Q)), np.max(np.abs(Vr - V))))
        if row["finished"]:
            row.update(errors(p, ref, Qr, Vr))
            med, lo, hi = timed(lambda: solve(p, method, setting, compiled=compiled), repeats)
            row.update({"time_median_s": med, "time_min_s": lo, "time_max_s": hi, "repeats": repeats})
        else:
            row.update({"final_error": float("inf"), "trajectory_error": float("inf"), "energy_drift": float("nan"),
                        "constraint_residual": float("nan"), "time_median_s": float("nan"), "time_min_s": float("nan"),
                        "time_max_s": float("nan"), "repeats": 0})  # fmt: skip
        rows.append(row)
    return rows


def settings(p: Problem, method: str, n_fixed: int = 6, n_adaptive: int = 5) -> list[float]:
    """``dt = interval 2^-k`` (k = 0 .. n_fixed - 1) or ``rtol`` from 1e-3 to 1e-11 (``n_adaptive`` values)."""
    if method in ADAPTIVE:
        return [float(x) for x in np.logspace(-3, -11, n_adaptive)]
    return [p.interval * 2.0**-k for k in range(n_fixed)]


def cheapest(rows: list[dict[str, Any]], target: float, key: str = "trajectory_error") -> dict[str, Any] | None:
    """The run with the least median time whose ``key`` is at most ``target`` (finished runs only)."""
    ok = [r for r in rows if r["finished"] and r[key] <= target]
    return min(ok, key=lambda r: r["time_median_s"]) if ok else None
