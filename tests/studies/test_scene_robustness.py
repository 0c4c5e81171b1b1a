"""The six-axis robustness sweep on every scene (mbs_envs.studies.scene_robustness)."""

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.studies import scene_robustness as sr
from mbs_envs.studies.comparison import SCENES
from mbs_envs.studies.evaluation import Episode
from mbs_envs.studies.robustness import Perturbation, random_pulses, run


def nominal(scene):
    return gym.make(SCENES[scene][0], **SCENES[scene][1])


def test_every_compared_scene_has_a_sweep():
    assert set(sr.SWEEPS) == set(SCENES)


@pytest.mark.parametrize("scene", sorted(sr.SWEEPS))
def test_model_variations_scale_one_parameter_each_and_keep_the_actuators(scene):
    env = nominal(scene).unwrapped
    p, n = env.model.params, 3
    spec = sr.SWEEPS[scene]
    pts = sr.model_variations(scene, p, env.u_max, env.model, n)
    assert len(pts) == len(spec.factors) * n + len(spec.damping) * 2
    assert all(c is not None for _, _, c in pts)  # +-25 %: every variation is a valid plant
    for name, value, changes in pts:
        assert set(changes) == {name}
        if name in spec.factors:
            np.testing.assert_allclose(changes[name], np.asarray(getattr(p, name)) * value, rtol=1e-15)
        else:  # damping: from 0 to DAMPING_RATE x the torque scale of its coordinates
            top = sr.DAMPING_RATE * sr.torque_scale(env.model, env.u_max)[list(spec.damping[name])].max()
            assert 0.0 <= value <= top + 1e-15
    # the env built from a variation has the changed parameter and the nominal torque limits
    from mbs_envs.studies.comparison import model_kwargs

    name, value, changes = pts[-1 - 2 * len(spec.damping)]
    varied = gym.make(SCENES[scene][0], **model_kwargs(scene, changes)).unwrapped
    np.testing.assert_allclose(getattr(varied.model.params, name), changes[name], rtol=1e-15)
    np.testing.assert_array_equal(varied.u_max, env.u_max)


def test_torque_scale_is_the_driving_input_limit_or_the_largest():
    acro = nominal("Acrobot").unwrapped  # the shoulder is undriven
    np.testing.assert_array_equal(sr.torque_scale(acro.model, acro.u_max), [10.0, 10.0])
    arm = nominal("Planar2R").unwrapped
    np.testing.assert_array_equal(sr.torque_scale(arm.model, arm.u_max), arm.u_max)


@pytest.mark.parametrize("scene, expected", [("Acrobot", (4, 5)), ("Planar2R", (4, 5)), ("RollingDisk", (1, 2, 3))])
def test_velocity_entries_are_those_of_the_decoded_velocities(scene, expected):
    """Against each env's own observation layout (decode_observation)."""
    assert sr.velocity_entries(nominal(scene)) == expected


def test_generic_pulses_keep_each_coordinates_height_range_and_spacing():
    t = np.arange(1000) * 0.01
    lo, hi = np.array([0.1, 1.0, 5.0]), np.array([0.2, 2.0, 10.0])
    P = random_pulses(np.random.default_rng(1), 20, t, 3, 2, 1.0, (0.05, 0.1), (lo, hi))
    assert P.shape == (20, 1000, 3)
    for e in range(20):
        peaks = np.abs(P[e]).max(axis=0)
        assert np.all(peaks >= 0.95 * lo) and np.all(peaks <= hi + 1e-12)
    with pytest.raises(ValueError, match="gap"):
        random_pulses(np.random.default_rng(1), 2, t, 3, 4, 1.0, (0.05, 0.1), (lo, hi))  # 12 pulses 1 s apart in 10 s


def test_pulses_move_a_constrained_plant_and_keep_its_constraints():
    v = gym.make_vec("mbs_envs/FourBar-v0", num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                     max_episode_steps=30)  # fmt: skip
    pulses = np.zeros((2, 30, 3))
    pulses[1, 5:15, 0] = 2.0

    class Hold:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros((len(obs), 1), np.float32), state

    res = run(v, Hold(), [0, 0], Perturbation(pulses=pulses))
    assert np.abs(res["q"][1] - res["q"][0]).max() > 1e-3
    np.testing.assert_allclose(v.unwrapped.model.constraint_residual(res["q"]), 0.0, atol=1e-9)


def episode(err, terminated=False, upright=None):
    t = np.arange(1, len(err) + 1) * 0.01
    return Episode(t=t, tracking_error=np.asarray(err, float)[:, None], u=np.zeros((len(t), 1)), reward=np.zeros(len(t)),
                   compute_time=np.zeros(len(t)), diverged=False, terminated=terminated,
                   upright=upright, power=None if upright is None else np.zeros(len(t)))  # fmt: skip


def test_success_rule_of_a_tracking_scene():
    ok = episode(np.r_[np.full(99, 1.0), np.full(401, 0.099)])  # large only before the first second (t < 1 s)
    bad = episode(np.full(500, 0.101))
    fell = episode(np.full(500, 0.0), terminated=True)
    np.testing.assert_array_equal(sr.success("Planar2R", [ok, bad, fell]), [True, False, False])


def test_success_rule_of_a_swing_up_scene_is_the_comparisons():
    up = np.r_[np.zeros(1000, bool), np.ones(500, bool)]
    late = np.r_[np.zeros(1400, bool), np.ones(100, bool)]  # upright for only the last second
    eps = [episode(np.zeros(1500), upright=up), episode(np.zeros(1500), upright=late)]
    np.testing.assert_array_equal(sr.success("Acrobot", eps), [True, False])


def test_sweep_bookkeeping_on_a_tiny_grid(monkeypatch):
    """Two values per axis, two seeds, three pulse episodes, short episodes: the members of every axis are the
    values times the seeds in that order, the fractions are their means and the score the mean of the fractions;
    with perfect tracking impossible in 0.3 s (the first second is excluded: no settled error), nothing succeeds."""
    monkeypatch.setattr(gym.envs.registration.registry["mbs_envs/Planar2R-v0"], "max_episode_steps", 30)
    tiny = sr.SceneSweep(("m2",), {"b1": (0,)}, (0,), pulses_per_coordinate=1, pulse_gap=0.1)
    monkeypatch.setattr(sr, "SWEEPS", {**sr.SWEEPS, "Planar2R": tiny})
    from mbs_envs.studies.comparison import load_policy

    res = sr.sweep(
        "Planar2R", lambda env: load_policy(SCENES["Planar2R"][2]["PD"], env), n=2, seeds=(5, 6), pulse_episodes=3
    )
    assert set(res) == set(sr.AXES) | {"score"}
    assert res["model"]["values"] == [("m2", 0.75), ("m2", 0.75), ("m2", 1.25), ("m2", 1.25), ("b1", 0.0), ("b1", 0.0)]
    assert res["model"]["seeds"] == [5, 6] * 3
    assert res["velocity noise"]["values"] == [0.0, 0.0, 0.5, 0.5] and res["velocity noise"]["seeds"] == [5, 6, 5, 6]
    assert res["time delay"]["values"] == [0.0, 0.0, 0.05, 0.05]
    assert res["perturbations"]["seeds"] == [5, 6, 5]
    for a in sr.AXES:
        assert res[a]["fraction"] == np.mean(res[a]["success"])
    assert res["score"]["value"] == pytest.approx(np.mean([res[a]["fraction"] for a in sr.AXES]))
    assert res["score"]["value"] == 0.0


def test_unperturbed_members_of_every_axis_are_the_nominal_episode():
    """A zero setting of each axis (noise 0, response 1, delay 0, factor 1 via member_params) gives the plain
    rollout's episode bit for bit."""
    from mbs_envs.studies.comparison import load_policy
    from mbs_envs.studies.evaluation import rollout_batch

    env_id = SCENES["Acrobot"][0]

    def venv(**kw):
        return gym.make_vec(
            env_id,
            num_envs=2,
            vectorization_mode="vector_entry_point",
            autoreset_mode="Disabled",
            max_episode_steps=60,
            **kw,
        )

    policy = lambda: load_policy(SCENES["Acrobot"][2]["swing-up + LQR"], gym.make(env_id))  # noqa: E731
    plain = rollout_batch(venv(), policy(), [3, 4])
    settings = [Perturbation(noise_sigma=np.zeros(2), noise_index=(4, 5)), Perturbation(torque_sigma=np.zeros((2, 1))),
                Perturbation(response=np.ones(2)), Perturbation(delay=np.zeros(2, int)), Perturbation(pulses=np.zeros((2, 60, 2)))]  # fmt: skip
    for p in settings:
        eps = run(venv(), policy(), [3, 4], p, record=True)["episodes"]
        for a, b in zip(eps, plain):
            np.testing.assert_array_equal(a.tracking_error, b.tracking_error)
            np.testing.assert_array_equal(a.u, b.u)
            np.testing.assert_array_equal(a.reward, b.reward)
    eps = run(venv(member_params=[{"m2": 1.0}, {"m2": 1.0}]), policy(), [3, 4], Perturbation(), record=True)["episodes"]
    np.testing.assert_array_equal(eps[1].tracking_error, plain[1].tracking_error)
