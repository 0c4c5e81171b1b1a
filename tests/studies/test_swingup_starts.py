"""Training starts along a model-based swing-up (:mod:`mbs_envs.studies.swingup_starts`): the states are the
episode's, from hanging at rest up to the first within the tolerance; the DFKI ids take the score-designed plan; bad
arguments are refused before any rollout."""

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.envs.swingup import Q_DOWN
from mbs_envs.studies.swingup_starts import controller_states, swingup_starts


class Push:
    """A constant torque (the stub of a controller: ``predict`` as SB3's)."""

    def __init__(self, a: float):
        self.a = np.array([a], np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.a, state


def test_controller_states_are_the_episode_up_to_the_first_within_the_tolerance():
    # a wide tolerance (3 rad: hanging is pi from upright) that a constant push reaches within a few steps
    env = gym.make("mbs_envs/Pendubot-v2", upright_tolerance=3.0)
    X = controller_states(env, Push(1.0))
    ref = gym.make("mbs_envs/Pendubot-v2", upright_tolerance=3.0)  # the same episode stepped here
    ref.reset(options={"q": np.array(Q_DOWN), "v": np.zeros(2)})
    rows, upright = [], False
    while not upright:
        rows.append(np.concatenate([ref.unwrapped.q, ref.unwrapped.v]))
        upright = ref.step(np.array([1.0], np.float32))[4]["upright"]
    np.testing.assert_allclose(X, np.array(rows), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(X[0], np.concatenate([Q_DOWN, np.zeros(2)]))
    assert 2 < len(X) < 200 and np.all(np.abs(X[:, :2]) <= np.pi)


def test_controller_states_end_with_the_episode_if_it_never_reaches_the_tolerance():
    env = gym.make("mbs_envs/Acrobot-v2", max_episode_steps=40)
    X = controller_states(env, Push(0.0))  # hanging still
    assert X.shape == (40, 4)
    np.testing.assert_allclose(X, np.tile(np.concatenate([Q_DOWN, np.zeros(2)]), (40, 1)), rtol=0, atol=1e-12)


def test_controller_states_wrap_the_angles_of_a_spinning_arm():
    """The acrobot's elbow pushed at full torque spins (hundreds of rad): the rows hold its angle wrapped to
    [-pi, pi), the rates as they are."""
    from mbs_envs.envs.tracking import wrap_angle

    env = gym.make("mbs_envs/Acrobot-v2", max_episode_steps=300)
    X = controller_states(env, Push(1.0))
    ref = gym.make("mbs_envs/Acrobot-v2", max_episode_steps=300)
    ref.reset(options={"q": np.array(Q_DOWN), "v": np.zeros(2)})
    raw = []
    for _ in range(300):
        raw.append(np.concatenate([ref.unwrapped.q, ref.unwrapped.v]))
        assert not ref.step(np.array([1.0], np.float32))[4]["upright"]
    raw = np.array(raw)
    assert np.abs(raw[:, 1]).max() > 10 * np.pi  # the elbow went round several times
    np.testing.assert_allclose(X[:, :2], wrap_angle(raw[:, :2]), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(X[:, 2:], raw[:, 2:])
    assert np.all((X[:, :2] >= -np.pi) & (X[:, :2] < np.pi))


@pytest.mark.parametrize(
    "args, match",
    [
        (("mbs_envs/Planar2R-v0", 0.5), "no swing-up of the arm"),
        (("mbs_envs/CartPoleSwingUp-v0", 0.5), "no swing-up of the arm"),
        (("Acrobot", 0.5), "no swing-up of the arm"),
        ((None, 0.5), "no swing-up of the arm"),
        (("mbs_envs/Acrobot-v2", 1.5), "share"),
        (("mbs_envs/Acrobot-v2", float("nan")), "share"),
        (("mbs_envs/Acrobot-v2", "0.5"), "share"),
    ],
)
def test_swingup_starts_refuses_before_any_rollout(args, match):
    with pytest.raises(ValueError, match=match):
        swingup_starts(*args)


@pytest.mark.parametrize("stride", [0, -1, 1.5, True])
def test_swingup_starts_refuses_a_bad_stride(stride):
    with pytest.raises(ValueError, match="stride"):
        swingup_starts("mbs_envs/Pendubot-v2", 0.5, stride=stride)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["mbs_envs/Acrobot-v2", "mbs_envs/Pendubot-v2"])
def test_swingup_starts_follow_the_planner_from_hanging_to_its_hand_over(env_id):
    from mbs_envs.envs import registry
    from mbs_envs.studies.evaluation import default_gains_entry, make_controller
    from mbs_envs.studies.swingup_starts import CONTROLLER

    bank = swingup_starts(env_id, 0.3, stride=5)
    rows = np.array(bank["rows"])
    env = gym.make(env_id)
    spec = registry.scene(env_id).controllers[CONTROLLER]
    X = controller_states(env, make_controller(spec, env, default_gains_entry(spec, env)))
    np.testing.assert_allclose(rows, X[::5], rtol=0, atol=1e-12)  # the same deterministic episode
    assert bank["share"] == 0.3 and len(X) < 1500  # it reached the tolerance
    np.testing.assert_array_equal(rows[0], np.concatenate([Q_DOWN, np.zeros(2)]))
    trained = gym.make(env_id, start_states=bank)  # the env takes the setting as JSON gives it
    assert trained.unwrapped.start_states.rows.shape == rows.shape
