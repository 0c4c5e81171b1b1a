"""What an upright LQR catches under the torque limit, and what physics allows (the catch's region of attraction).

- :func:`saturation_bound` -- **what physics allows.** For an unstable eigenvalue ``lambda > 0`` with left eigenvector
  ``w`` (``w^T A = lambda w^T``) of the linearization ``dx/dt = A x + B u`` (``|u| <= u_max``) the mode ``z = w^T x``
  obeys ``dz/dt = lambda z + (w^T B) u``; once ``|z| >= |w^T B| u_max / lambda`` no admissible input brings it back.
  Along one coordinate ``j`` (the others zero) a state is catchable only if
  ``|x_j| < |w^T B| u_max / (lambda |w_j|)``, minimized over the unstable modes: a necessary condition of the
  linearization.
- :func:`estimate_region` -- **what a given feedback catches**, by simulation: states drawn uniformly in a box about
  upright, then below the level found so far, each run in closed loop ``u = clip(-K x)`` on the discrete map the env
  integrates (:func:`controllers.control_map.fast_map`), on every plant of a set; the estimate is the largest level
  ``c*`` of the LQR's cost-to-go ``x^T S x`` below which no sample failed (a sampled estimate, not a certificate).
  :func:`axis_catch` -- the same along one coordinate: the largest offset caught.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .control_map import fast_map, state_error


def saturation_bound(A: np.ndarray, B: np.ndarray, u_max: float, delay: float = 0.0) -> np.ndarray:
    """The largest catchable offset along each state coordinate (module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 1)
    u_max : float
        [N m].
    delay : float
        Input delay [s]: the mode grows unopposed by ``e^(lambda delay)`` before the input acts,
        so each slab shrinks by that factor.

    Returns
    -------
    ndarray, shape (n,)
        Per coordinate (others zero): ``min over unstable modes of |w^T B| u_max / (lambda |w_j|)``;
        ``inf`` where no unstable mode constrains it.
    """
    lam, W = np.linalg.eig(A.T)
    bound = np.full(A.shape[0], np.inf)
    for i in np.flatnonzero(lam.real > 1e-9):
        w = W[:, i].real if abs(lam[i].imag) < 1e-12 else None
        if w is None:  # a complex unstable pair: its modulus obeys no such slab (not the case of these arms)
            continue
        reach = abs(w @ B[:, 0]) * u_max / lam[i].real * np.exp(-lam[i].real * delay)
        with np.errstate(divide="ignore"):
            bound = np.minimum(bound, np.where(np.abs(w) > 1e-12, reach / np.abs(w), np.inf))
    return bound


@dataclasses.dataclass(frozen=True)
class PlantCase:
    """One plant of the set a region is checked on: its model and the input delay [control steps]."""

    model: Any
    delay: int = 0


def closed_loop_final(cases: list[PlantCase], x0: np.ndarray, x_goal: np.ndarray, K: np.ndarray, u_max: float,
                      dt: float, substeps: int, steps: int, box: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """The error ``x_N - x_goal`` after ``steps`` of ``u = clip(-K (x - x_goal))`` from each start, on each plant.

    Parameters
    ----------
    x0 : ndarray, shape (S, n)
    box : ndarray, shape (n,), optional
        Half-widths of a box about ``x_goal`` (angles wrapped): a run that leaves it at any step is
        marked as diverged (a controller that hands back at the box's edge never sees it return,
        and a run that goes once around and comes back upright is no catch).

    Returns
    -------
    ndarray, shape (len(cases), S, n)
        Non-finite rows where a run diverged.
    """
    out = []
    for case in cases:
        x = np.array(x0, float)
        queue = [np.zeros((len(x), 1))] * case.delay
        with np.errstate(all="ignore"):
            for _ in range(steps):
                u = np.clip(-(state_error(x, x_goal) @ K.T), -u_max, u_max)
                queue.append(u)
                x = fast_map(case.model, x, queue.pop(0), dt, substeps)
                x = np.where(np.abs(x) < 1e6, x, np.nan)
                if box is not None:
                    x = np.where(np.all(np.abs(state_error(x, x_goal)) <= box, axis=-1, keepdims=True), x, np.nan)
        out.append(state_error(x, x_goal))
    return np.array(out)


def estimate_region(cases: list[PlantCase], x_goal: np.ndarray, K: np.ndarray, S: np.ndarray, u_max: float, dt: float,
                    substeps: int, half_widths: np.ndarray, samples: int = 1000, rounds: int = 12, horizon: float = 5.0,
                    tol: float = 0.1, seed: int = 0) -> tuple[float, dict]:  # fmt: skip
    """The catch level ``c*`` of ``u = clip(-K x)`` on every plant of ``cases`` (module docstring).

    Sampling as LQR-trees shrink a funnel: a first round draws ``samples`` states uniformly in the
    box ``|x - x_goal| <= half_widths``; each later round draws them uniformly in the part of the box
    below the current level (``x^T S x < c``, by rejection). Each state runs in closed loop on every
    plant; one that is not within ``tol`` (max norm) of ``x_goal`` after ``horizon`` seconds on some
    plant is a failure, and the level drops to the cost-to-go ``x^T S x`` of the cheapest failure.
    The rounds stop when one finds no failure below the level (or after ``rounds``). The box should
    reach beyond the saturation bound (:func:`saturation_bound`), so that failures bound the level
    and not the box.

    Returns
    -------
    level : float
    details : dict
        ``rounds`` run, ``samples`` in all, ``converged`` (the last round found no failure below the
        level), ``bounded_by_box`` (no failure at all: the level is the box's costliest sample).
    """
    rng = np.random.default_rng(seed)
    half_widths = np.asarray(half_widths, float)
    level, total, converged, failed_any = np.inf, 0, False, False
    for r in range(rounds):
        dx = np.empty((0, len(x_goal)))
        for _ in range(200):  # rejection: uniform in the box below the level
            draw = rng.uniform(-1.0, 1.0, (4 * samples, len(x_goal))) * half_widths
            dx = np.concatenate([dx, draw[np.einsum("bi,ij,bj->b", draw, S, draw) < level]])[:samples]
            if len(dx) == samples:
                break
        total += len(dx)
        err = closed_loop_final(
            cases, x_goal + dx, x_goal, K, u_max, dt, substeps, int(round(horizon / dt)), half_widths
        )
        ok = np.all(np.all(np.abs(err) <= tol, axis=-1), axis=0)  # NaN compares False: a diverged run is not caught
        cost = np.einsum("bi,ij,bj->b", dx, S, dx)
        if r == 0 and ok.all():
            return float(cost.max()), {"rounds": 1, "samples": total, "converged": True, "bounded_by_box": True}
        if ok.all():
            converged = True
            break
        failed_any = True
        level = float(cost[~ok].min())
    return level, {"rounds": r + 1, "samples": total, "converged": converged, "bounded_by_box": not failed_any}


def axis_catch(case: PlantCase, x_goal: np.ndarray, K: np.ndarray, u_max: float, dt: float, substeps: int, axis: int,
               high: float, points: int = 64, horizon: float = 5.0, tol: float = 0.1) -> float:  # fmt: skip
    """The largest offset along one state coordinate (others zero, both signs) from which ``u = clip(-K x)``
    brings ``case``'s plant within ``tol`` of ``x_goal`` in ``horizon`` seconds, on a grid of ``points``
    offsets in ``(0, high]`` (every smaller grid offset caught too); 0 if the first is not caught."""
    d = np.linspace(high / points, high, points)
    x0 = np.repeat(x_goal[None], 2 * points, axis=0)
    x0[:points, axis] += d
    x0[points:, axis] -= d
    err = closed_loop_final([case], x0, x_goal, K, u_max, dt, substeps, int(round(horizon / dt)))[0]
    ok = np.all(np.abs(err) <= tol, axis=-1)
    ok = ok[:points] & ok[points:]
    return float(d[np.argmin(ok)] - high / points) if not ok.all() else float(high)
