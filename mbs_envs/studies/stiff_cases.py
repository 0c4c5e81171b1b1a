"""Stiff and extreme cases: which integrators stay stable at which step, and
whether a failure is reported (the logic of ``scripts/stiff_cases.py``).

Every case is a :class:`mbs_envs.studies.numerics.Case`. :func:`scan` runs one
fixed-step integrator from the coarsest step down, halving, until a run is
*stable*: not flagged as diverged and within ``accept`` of the reference at
the final time (a bounded but wrong answer is not stable). Runs that are
neither stable nor flagged are *silent failures* and counted. Cases whose
true motion ends in a singularity (the disk falling flat) are scored on
whether that is reported instead (:func:`singular_case_row`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..dynamics import integrators
from . import numerics
from .numerics import computed_torque_law, pd_law  # noqa: F401  (the laws of the stiff cases)
from ..models.base import Model
from ..dynamics.simulate import acceleration, simulate
from .scene_cases import drive_chain
from ..models import FourBar, Planar2R

Case = numerics.Case


def spectral_radius(case: Case) -> float:
    """Largest ``|eigenvalue|`` of the linearized first-order system at the start [1/s].

    ``J = [[0, I], [da/dq, da/dv]]`` with finite-difference ``da/dq``, ``da/dv``
    (:func:`mbs_envs.dynamics.integrators.acceleration_jacobian`). An explicit method
    with real stability interval ``[-beta, 0]`` needs ``dt < beta / rho``
    (RK4: ``beta = 2.785``) when the fast eigenvalue is real and negative.
    """
    stab = case.model.stabilization(case.stabilization)
    acc = acceleration(case.model, case.u, stab)
    A_q, A_v = integrators.acceleration_jacobian(acc, 0.0, np.asarray(case.q0, float), np.asarray(case.v0, float))
    n = A_q.shape[-1]
    J = np.block([[np.zeros((n, n)), np.eye(n)], [A_q, A_v]])
    return float(np.max(np.abs(np.linalg.eigvals(J))))


def stiff_cases(quick: bool = False) -> list[Case]:
    """The stiff and extreme cases of the report (see ``docs/numerics.md``): each scene's, as its
    registry entry declares them (:attr:`mbs_envs.envs.registry.Scene.stiff_cases`)."""
    from ..envs import registry

    return [c for s in registry.SCENES if s.stiff_cases for c in registry.load(s.stiff_cases)(quick)]


def singular_cases() -> list[Case]:
    """Cases whose true motion ends at a coordinate singularity (the disk falling flat), from the registry."""
    from ..envs import registry

    return [c for s in registry.SCENES if s.singular_cases for c in registry.load(s.singular_cases)()]


def scan(case: Case, ref: numerics.Reference, method: str, dts: list[float], accept: float = 1e-2,
         budget_s: float = 60.0) -> list[dict[str, Any]]:  # fmt: skip
    """Run ``method`` at ``dts`` (coarsest first) until a run is stable, or until the runs so far
    have used ``budget_s`` seconds of CPU (the finer steps are then not tried: a dense-Jacobian
    method on a 500-link chain over 5 s would take hours); return every row.

    Each row is :func:`mbs_envs.studies.numerics.score`'s with ``stable`` and
    ``silent_failure`` added. Where the reference itself is not determined to
    ``accept`` (its error estimate is larger: motion through a change point,
    where the branch taken is decided by rounding), stability is judged on the
    invariants instead: energy error at most ``accept`` J and constraint error
    at most 1e-6.
    """
    ill_posed = ref.error_estimate > accept
    rows = []
    for dt in sorted(dts, reverse=True):
        row = numerics.score(case, ref, method, dt)
        if ill_posed:
            ok = row["energy_error"] <= accept and not row["constraint_error"] > 1e-6
            row["state_error"] = row["trajectory_error"] = float("nan")
        else:
            ok = row["trajectory_error"] <= accept
        row["stable"] = (not row["diverged"]) and bool(ok)
        row["silent_failure"] = (not row["diverged"]) and not row["stable"]
        rows.append(row)
        if row["stable"] or sum(r["cpu_s"] for r in rows) > budget_s:
            break
    return rows


def summarize_scan(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """One table row from a :func:`scan`: the largest stable step and what happened above it."""
    stable = [r for r in rows if r["stable"]]
    best = stable[0] if stable else None
    unstable = [r for r in rows if not r["stable"]]
    return {
        "scene": rows[0]["scene"],
        "integrator": rows[0]["integrator"],
        "largest_stable_dt": None if best is None else best["setting"],
        "state_error": None if best is None else best["state_error"],
        "trajectory_error": None if best is None else best["trajectory_error"],
        "energy_error": None if best is None else best["energy_error"],
        "constraint_error": None if best is None else best["constraint_error"],
        "cpu_s": None if best is None else best["cpu_s"],
        "unstable_runs": len(unstable),
        "unstable_flagged": sum(r["diverged"] for r in unstable),
        "silent_failures": sum(r["silent_failure"] for r in rows),
        "halvings": sum(r["halvings"] or 0 for r in rows),
        "finest_dt_tried": min(r["setting"] for r in rows),
    }


def singular_case_row(case: Case, method: str, dt: float) -> dict[str, Any]:
    """Run a case that must end in its singularity: was it reported, and were all outputs finite?"""
    opts = {"rtol": 1e-8, "atol": 1e-8} if integrators.get(method).adaptive else {}
    step = 0.01 if opts else dt
    tr = simulate(case.model, case.q0, case.v0, case.t_final, dt=step, integrator=method, u=case.u,
                  stabilization=case.stabilization, **opts)  # fmt: skip
    finite = bool(np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v)))
    flagged = bool(np.any(tr.diverged))
    if tr.q.ndim > 1 and flagged:
        # fixed step: the member is held at its last finite state from the flag on
        moved = np.any(np.diff(tr.q, axis=0) != 0, axis=-1)
        t_flag = float(tr.t[np.flatnonzero(moved)[-1] + 1]) if moved.any() else 0.0
    else:
        t_flag = float(tr.t[-1]) if flagged else None
    lean = np.abs(tr.q[..., 4])
    return {
        "scene": case.scene,
        "integrator": method,
        "dt": step,
        "flagged": flagged,
        "all_outputs_finite": finite,
        "t_flagged": t_flag,
        "max_lean_reported": float(np.max(lean)),
    }


@dataclasses.dataclass(frozen=True)
class LongRun:
    """A long horizon: many fixed steps of free, conservative motion."""

    scene: str
    model: Model
    q0: np.ndarray
    v0: np.ndarray
    steps: int
    dt: float
    stabilization: str | None = None


def long_runs(quick: bool = False) -> list[LongRun]:
    n = 2_000 if quick else 100_000
    fb = FourBar()
    q, v = fb.consistent_state(0.2, 4.0)
    return [
        LongRun("2R free swing", Planar2R(), np.array([-np.pi / 2 + 0.3, 0.2]), np.zeros(2), n, 1e-3),
        LongRun("four-bar free, projection", fb, q, v, n, 1e-3, "projection"),
    ]


def long_run_row(run: LongRun, method: str) -> dict[str, Any]:
    """Energy and constraint drift over ``run.steps`` fixed steps."""
    import time

    c0 = time.process_time()
    tr = simulate(
        run.model,
        run.q0,
        run.v0,
        run.steps * run.dt,
        dt=run.dt,
        integrator=method,
        stabilization=run.stabilization,
        compiled=False,
    )  # CPU times of methods on one implementation
    cpu = time.process_time() - c0
    E = run.model.energy(tr.q, tr.v)
    return {
        "scene": run.scene,
        "integrator": method,
        "steps": run.steps,
        "dt": run.dt,
        "diverged": bool(np.any(tr.diverged)),
        "energy_drift": float(np.max(np.abs(E - E[0]))),
        "energy_drift_relative": float(np.max(np.abs(E - E[0])) / max(abs(float(E[0])), 1e-300)),
        "constraint_error": numerics.constraint_error(run.model, tr.q, tr.v),
        "cpu_s": cpu,
    }


# -- the O(N) implicit joint step on long chains (scripts/implicit_chain.py) ------------------


def stiff_pd_chain(n: int, bandwidth: float = 1000.0):
    """SerialChain-v0's ``n``-link chain (drives with armature) under a joint PD of ``bandwidth``
    [rad/s] per joint: ``K_p = w^2 J_i``, ``K_d = 2 w J_i`` on the apparent inertia
    ``J_i = 1 / (M^-1)_ii`` at the hanging posture, target hanging with the first joint
    0.3 rad off. Returns ``(model, q0, v0, law, target)``; the start hangs at rest."""
    from ..dynamics.inputs import JointPD

    model = drive_chain(n)
    hanging = np.r_[-np.pi / 2, np.zeros(n - 1)]
    J = 1.0 / np.diag(np.linalg.inv(model.mass_matrix(hanging)))
    target = hanging + np.r_[0.3, np.zeros(n - 1)]
    return model, hanging, np.zeros(n), JointPD(bandwidth**2 * J, 2 * bandwidth * J, target), target


def step_time(model: Model, method: str, compiled: bool, steps: int = 20, repeats: int = 5, h: float = 0.01) -> float:
    """Median wall time [s] of one step of ``h`` under a held zero torque, the way an environment steps
    (:func:`mbs_envs.dynamics.simulate.advance`): a warm-up, then ``repeats`` loops of ``steps`` steps."""
    import time

    from ..dynamics.simulate import advance

    stepper = integrators.get(method)
    q0, v0 = np.r_[-np.pi / 2 + 0.3, np.full(model.nq - 1, 0.3 / model.nq)], np.zeros(model.nv)
    u = np.zeros(model.nu)
    advance(model, stepper, 0.0, q0, v0, h, 1, u, None, compiled)
    times = []
    for _ in range(repeats):
        q, v = q0, v0
        t0 = time.perf_counter()
        for k in range(steps):
            q, v = advance(model, stepper, k * h, q, v, h, 1, u, None, compiled)
        times.append((time.perf_counter() - t0) / steps)
    return float(np.median(times))


def largest_settling_step(
    n: int, method: str, dts: list[float], t_final: float = 5.0, tol: float = 1e-3
) -> dict[str, Any]:
    """Largest ``dt`` (scanned from the coarsest) at which :func:`stiff_pd_chain` runs without
    divergence and ends within ``tol`` of its target (it settles in ~10 ms; ``t_final`` 5 s)."""
    model, q0, v0, law, target = stiff_pd_chain(n)
    flagged = 0
    for dt in sorted(dts, reverse=True):
        tr = simulate(model, q0, v0, t_final, dt=dt, integrator=method, u=law)
        if bool(np.any(tr.diverged)):
            flagged += 1
            continue
        error = float(np.max(np.abs(tr.q[-1] - target)))
        if error <= tol:
            return {
                "n_links": n,
                "integrator": method,
                "largest_stable_dt": dt,
                "final_error": error,
                "flagged_above": flagged,
            }
    return {
        "n_links": n,
        "integrator": method,
        "largest_stable_dt": None,
        "final_error": None,
        "flagged_above": flagged,
    }


# -- what to pick, at the environments' control step (scripts/what_to_pick.py) ----------------

#: the environments' control step [s]
CONTROL_DT = 0.01
#: physics steps per control step tried, in order (the environments' ``substeps``)
SUBSTEPS = (1, 2, 4, 8, 16)


def regimes() -> list[tuple[str, Case]]:
    """One case per scene and regime: each scene's environment model under a held torque (nominal),
    the disk at 100x its critical spin, stiff viscous, Coulomb and Stribeck friction on the 2R, and a
    200-link chain under a 1000 rad/s joint PD (long chain); 1 s each."""
    import gymnasium as gym

    from ..envs import registry

    out = []
    for s in registry.SCENES:
        env = gym.make(s.id, **dict(s.kwargs)).unwrapped
        env.reset(seed=0)
        stab = getattr(env.stabilization, "kind", None)
        out.append(("nominal", Case(f"{s.name} (environment model, 0.3 u_max held)", env.model, env._q.copy(), env._v.copy(),
                                    1.0, u=0.3 * np.asarray(env.u_max, float), stabilization=stab, conservative=False)))  # fmt: skip
        env.close()
    stiff = {c.scene: c for c in stiff_cases()}
    out.append(("high spin", stiff["disk 100x critical spin"]))
    for name in ("viscous b=400", "Coulomb f=2, v_s=1e-4", "Stribeck f=1, df=1, v_st=0.05, v_s=1e-3"):
        out.append(("stiff friction", stiff[name]))
    model, q0, v0, law, _ = stiff_pd_chain(200)
    out.append(("long chain", Case("chain N=200, joint PD 1000 rad/s", model, q0, v0, 1.0, u=law, conservative=False,
                                   reference_method="radau")))  # fmt: skip
    return out


def pick_rows(case: Case, ref: numerics.Reference, method: str, accurate: float = 1e-6, usable: float = 1e-2,
              repeats: int = 3) -> list[dict[str, Any]]:  # fmt: skip
    """``method`` at the control step with ``SUBSTEPS`` physics steps, fewest first, until its trajectory
    error is at most ``accurate``: one row per run (trajectory error, flagged, median wall time of
    ``repeats`` runs after a warm-up, on the path an environment takes: compiled where it applies)."""
    from .work_precision import timed

    import time

    rows = []
    for k in SUBSTEPS:
        dt = CONTROL_DT / k
        t0 = time.perf_counter()
        tr = simulate(case.model, case.q0, case.v0, case.t_final, dt=dt, integrator=method, u=case.u,
                      stabilization=case.stabilization)  # fmt: skip
        first = time.perf_counter() - t0
        flagged = bool(np.any(tr.diverged))
        err = float("inf") if flagged else numerics.trajectory_error(tr, ref)
        run = lambda: simulate(case.model, case.q0, case.v0, case.t_final, dt=dt, integrator=method, u=case.u,  # noqa: E731
                               stabilization=case.stabilization)  # fmt: skip
        # a warm-up (the first run may have compiled kernels), then the median of the repeats (one for runs over a second)
        seconds = float("nan") if flagged else timed(run, 1 if first > 1.0 else repeats)[0]
        rows.append({"case": case.scene, "integrator": method, "substeps": k, "dt": dt, "flagged": flagged,
                     "trajectory_error": err, "usable": (not flagged) and err <= usable, "accurate": (not flagged) and err <= accurate,
                     "seconds": seconds})  # fmt: skip
        if rows[-1]["accurate"]:
            break
    return rows
