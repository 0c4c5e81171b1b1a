"""The tasks as pure functions of ``(q, v, t, task state, params)`` with explicit parameters
(Gymnasium's phys2d style): an episode replayed through them, with parameters written out here
rather than taken from an env, gives the env's observations, rewards, terminations and info."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import mbs_envs  # noqa: F401  (registers the ids)
from mbs_envs.envs import rolling_disk as disk
from mbs_envs.envs import swingup, tracking
from mbs_envs.envs.stacking import tree_pick


def test_tracking_task_functions_replay_a_planar2r_episode():
    p = tracking.TrackingTaskParams(
        tracked=(0, 1), weights=np.array([1.0, 0.1, 1e-3]), center_low=np.array([-np.pi / 2 - 1.0, -1.2]),
        center_high=np.array([-np.pi / 2 + 1.0, 1.2]), max_amplitude=np.array([0.6, 0.8]), omega_range=(0.5, 3.0),
        rate_range=None, n_components=3, start_noise=0.1,
    )  # fmt: skip
    env = gym.make("mbs_envs/Planar2R-v0").unwrapped
    assert all(np.array_equal(getattr(env.task_params, f), getattr(p, f)) for f in vars(p)), (
        "the env holds these parameters"
    )
    obs, _ = env.reset(seed=4)
    rng = np.random.default_rng(4)  # what reset(seed=4) seeds
    refs = tracking.sample(p, [rng])  # a batch of one member, drawn from its generator
    q, v = (x[0] for x in tracking.start_tracked(p, refs, [rng]))
    ref = tree_pick(refs, 0)
    np.testing.assert_array_equal(obs, tracking.observe(p, q, v, ref(0.0)))
    for k, a in enumerate(np.random.default_rng(0).uniform(-1, 1, (20, 2)).astype(np.float32)):
        obs, r, terminated, _, info = env.step(a)
        q, v, t = env.q, env.v, env.t
        now = ref(t)
        np.testing.assert_array_equal(obs, tracking.observe(p, q, v, now))
        r_f, terms = tracking.reward(p, q, v, now, a.astype(float))
        assert r == r_f and all(info[name] == x for name, x in terms.items()), k
        np.testing.assert_array_equal(info["tracking_error"], tracking.info(p, q, v, now)["tracking_error"])
        assert not terminated


def test_swing_up_task_functions_replay_an_acrobot_episode():
    p = swingup.SwingUpTaskParams(
        weights=np.array([1.0, 0.05, 0.01]), u_max=np.array([10.0]), driven=1, tolerance=0.1, start_noise=0.1
    )
    env = gym.make("mbs_envs/Acrobot-v0").unwrapped
    obs, _ = env.reset(seed=2)
    q, v = (x[0] for x in swingup.start(p, [np.random.default_rng(2)]))
    np.testing.assert_array_equal(obs, swingup.encode_swingup(q, v))
    for a in np.random.default_rng(1).uniform(-1, 1, (20, 1)).astype(np.float32):
        obs, r, *_, info = env.step(a)
        q, v = env.q, env.v
        r_f, terms = swingup.reward(p, q, v, a.astype(float))
        assert r == r_f and all(info[name] == x for name, x in terms.items())
        got = swingup.info(p, q, v, np.asarray(info["u"]) / p.u_max)
        np.testing.assert_array_equal(info["tracking_error"], got["tracking_error"])
        assert info["power"] == got["power"] and info["upright"] == got["upright"]


def test_disk_task_functions_replay_a_rolling_disk_episode():
    env = gym.make("mbs_envs/RollingDisk-v0").unwrapped
    Wc = env.model.critical_spin
    p = disk.DiskTaskParams(weights=np.array([1.0, 1.0, 0.1, 1e-3]), critical_spin=Wc, lean_limit=0.6, spin_range=(0.3, 2.0),
                            heading_amplitude=0.6, heading_omega=(0.2, 0.8))  # fmt: skip
    obs, _ = env.reset(seed=6)
    rng = np.random.default_rng(6)
    tasks = disk.sample(p, [rng])
    q, v = (x[0] for x in env.model.make_consistent(*disk.start(p, tasks, [rng], env.model)))
    task = tree_pick(tasks, 0)
    np.testing.assert_array_equal(obs, disk.observe(p, q, v, disk.reference(task, 0.0), task))
    for a in np.random.default_rng(3).uniform(-1, 1, (20, 2)).astype(np.float32):
        obs, r, terminated, _, info = env.step(a)
        q, v, now = env.q, env.v, disk.reference(task, env.t)
        np.testing.assert_array_equal(obs, disk.observe(p, q, v, now, task))
        r_f, terms = disk.reward(p, q, v, now, task, a.astype(float))
        assert r == r_f and all(info[name] == x for name, x in terms.items())
        assert terminated == disk.terminated(p, q, v, now, task)
        got = disk.info(p, q, v, now, task)
        assert info["lean"] == got["lean"] and info["spin_error"] == got["spin_error"]
        np.testing.assert_array_equal(info["tracking_error"], got["tracking_error"])
