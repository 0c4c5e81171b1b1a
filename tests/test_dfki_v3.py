"""The global-policy protocol (DFKI simulation v3): schedule, PID, uptime score and a short run."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.studies import dfki_v3


def test_the_schedule_is_the_leaderboards_rule_drawn_from_its_seed():
    """Targets ``U(0, 2 pi)^4 - pi`` with rates x4 (their angles), then times ``linspace(t/(n+1), t, n) + U(-1, 1)``,
    drawn in that order; ours are theirs minus ``(pi/2, 0)``; the same seed gives the same schedule."""
    s = dfki_v3.schedule(3)
    rng = np.random.default_rng(3)
    theirs = rng.uniform(0.0, 2 * np.pi, (15, 4)) - np.pi
    theirs[:, 2:] *= 4.0
    jitter = 2.0 * (rng.random(15) - 0.5)
    np.testing.assert_array_equal(s.targets[:, :2], theirs[:, :2] - np.array([np.pi / 2, 0.0]))
    np.testing.assert_array_equal(s.targets[:, 2:], theirs[:, 2:])
    np.testing.assert_array_equal(s.times[:-1], np.linspace(60.0 / 16, 60.0, 15) + jitter)
    assert s.times[-1] == np.inf and np.all(np.abs(s.times[:-1] - np.linspace(60.0 / 16, 60.0, 15)) <= 1.0)
    assert np.all(np.abs(s.targets[:, 2:]) <= 4 * np.pi) and np.all(np.abs(theirs[:, :2]) <= np.pi)
    again = dfki_v3.schedule(3)
    np.testing.assert_array_equal(again.times, s.times)
    assert not np.array_equal(dfki_v3.schedule(4).targets, s.targets)


def test_the_uptime_score_counts_the_samples_with_the_end_effector_above_the_threshold():
    l1, l2, dt = 0.2, 0.3, 0.002
    q = np.tile([-np.pi / 2, 0.0], (30000, 1))  # hanging throughout: 0
    assert dfki_v3.uptime_score(q, l1, l2, dt) == 0.0
    q[:7500] = (np.pi / 2, 0.0)  # upright for a quarter of the run
    assert dfki_v3.uptime_score(q, l1, l2, dt) == pytest.approx(0.25, abs=1e-12)
    # just below and just above 0.9 (l1 + l2): y = l1 + l2 cos(q2) with the first link upright
    below = np.arccos((0.9 * 0.5 - l1) / l2) + 1e-9
    q[:7500] = (np.pi / 2, below)
    assert dfki_v3.uptime_score(q, l1, l2, dt) == 0.0
    q[:7500] = (np.pi / 2, below - 2e-9)
    assert dfki_v3.uptime_score(q, l1, l2, dt) == pytest.approx(0.25, abs=1e-12)


def test_the_reset_pid_keeps_its_memory_over_the_run_and_differentiates_from_its_third_call():
    pid = dfki_v3.ResetPID(0.002)
    target = np.array([0.5, -0.2])
    u1 = pid(np.zeros(2), target)
    np.testing.assert_allclose(u1, 10.0 * target + 0.1 * target * 0.002, rtol=0, atol=1e-15)  # no derivative yet
    pid(np.zeros(2), target)
    u3 = pid(np.array([0.01, 0.0]), target)  # the error moved: the derivative acts, within the limit
    expected = 10 * 0.49 + 0.1 * (0.5 + 0.5 + 0.49) * 0.002 + 1.0 * (0.49 - 0.5) / 0.002
    assert abs(u3[0] - expected) < 1e-12 and abs(u3[1] - (10 * -0.2 + 0.1 * 3 * -0.2 * 0.002)) < 1e-12
    assert pid(np.array([0.5, 0.0]), target)[0] == -6.0  # a jump of the error: the derivative saturates
    assert pid.calls == 4 and np.allclose(pid.total, [1.49, -0.8])


def test_a_short_protocol_run_disturbs_the_arm_and_lets_the_controller_recover():
    """Disturbances in 6 s (those before its end): the PID drives the arm off upright, the swing-up + LQR brings it
    back up."""
    from mbs_envs.controllers.swingup import SwingUpLQR

    env_id = "mbs_envs/AcrobotDFKI-v1"
    r = dfki_v3.run(env_id, SwingUpLQR(gym.make(env_id)), seed=0, t_max=6.0, n=3)
    due = r["schedule"].times[r["schedule"].times < 6.0 - 0.2]
    resets = np.flatnonzero(np.diff(r["reset"].astype(int)) == 1) + 1
    assert len(due) >= 2 and len(resets) == len(due) and np.all(np.abs(r["T"][resets] - due) < 0.0021)
    assert 100 * len(due) <= r["reset"].sum() <= 101 * len(due)  # 0.2 s of 2-ms steps each
    assert np.all(np.isfinite(r["q"])) and 0.0 < r["score"] < 1.0
    assert np.all(np.abs(r["u"][~r["reset"], 0]) == 0.0)  # the acrobot's controller drives the elbow only
