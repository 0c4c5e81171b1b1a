"""The work-precision protocol: reference and floor, evaluation counts, timing, error measures, problems from the registry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mbs_envs.envs import registry
from mbs_envs.models import Planar2R
from mbs_envs.studies import work_precision as wp


@pytest.fixture(scope="module")
def free_2r():
    return wp.Problem("planar2r", "free", Planar2R(), np.array([-1.0, 0.8]), np.array([0.5, -1.0]), 0.04, 10)


def test_reference_floor_is_the_two_references_difference(free_2r):
    ref = wp.reference(free_2r)
    assert 0 < ref.floor < 1e-11
    Qb, Vb, ok = wp.solve(dataclasses.replace(free_2r), "radau", wp.REFERENCE_TOL)
    assert ok and ref.floor == max(np.max(np.abs(ref.q - Qb)), np.max(np.abs(ref.v - Vb)))
    e = wp.errors(free_2r, ref, ref.q, ref.v)
    assert e["final_error"] == e["trajectory_error"] == 0.0
    assert e["energy_drift"] < 1e-11  # the reference conserves the 2R's energy
    assert np.isnan(e["constraint_residual"])


def test_trajectory_error_sees_what_the_final_state_hides(free_2r):
    """A perturbation in the middle of the grid shows in the trajectory error only."""
    ref = wp.reference(free_2r)
    Q = ref.q.copy()
    Q[5, 0] += 1e-3
    e = wp.errors(free_2r, ref, Q, ref.v)
    assert e["final_error"] == 0.0 and e["trajectory_error"] == pytest.approx(1e-3, rel=1e-9)


@pytest.mark.parametrize("method, per_step", [("rk4", 4), ("midpoint", 2), ("euler", 1), ("joint_implicit_euler", 1)])
def test_evaluations_are_counted_per_member(free_2r, method, per_step):
    twin, calls = wp.counting(free_2r.model)
    wp.solve(free_2r, method, 0.02, model=twin)
    assert calls[0] == per_step * 20
    assert twin.params == free_2r.model.params  # the same parameters: only the counting differs


def test_implicit_steps_count_their_jacobians(free_2r):
    """SDIRK2 evaluates a (2 n)-member finite-difference Jacobian per step besides its Newton iterations."""
    twin, calls = wp.counting(free_2r.model)
    wp.solve(free_2r, "sdirk2", 0.04, model=twin)
    assert calls[0] >= 10 * (2 * 2 + 2)  # at least one Jacobian and one iteration per stage, 10 steps


def test_timed_warms_up_then_takes_median_and_min():
    calls = []
    med, lo, hi = wp.timed(lambda: calls.append(1), repeats=5)
    assert len(calls) == 6 and 0 <= lo <= med <= hi


def test_adaptive_free_is_one_solve_and_forced_restarts(free_2r):
    ref = wp.reference(free_2r)
    rows = wp.measure(free_2r, ref, "dop853", 1e-9, repeats=1)
    assert [r["kind"] for r in rows] == ["adaptive, one solve"] and rows[0]["trajectory_error"] < 1e-7
    forced = dataclasses.replace(free_2r, kind="forced", u=np.full((10, 2), 0.5))
    rows = wp.measure(forced, wp.reference(forced), "dop853", 1e-9, repeats=1)
    assert [r["kind"] for r in rows] == ["adaptive, restarted"]


def test_forced_problems_come_from_the_registry():
    problems = wp.forced_problems(0.05)
    assert [p.scene for p in problems] == [s.name.lower() for s in registry.SCENES]
    for p in problems:
        assert p.u.shape == (p.steps, p.model.nu) and np.all(np.isfinite(p.u))
        assert p.model.nc == 0 or p.stabilization == "projection"


def test_a_diverging_run_is_unfinished_and_never_scored_as_accurate(free_2r):
    stiff = dataclasses.replace(free_2r, model=Planar2R(b1=400.0, b2=400.0), kind="forced", u=np.full((10, 2), 30.0))
    ref = wp.reference(stiff)
    (row,) = wp.measure(stiff, ref, "euler", 0.04, repeats=1)[:1]
    assert not row["finished"] and row["trajectory_error"] == float("inf")
    assert wp.cheapest([row], 1e3) is None
