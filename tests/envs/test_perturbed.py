"""Training under the robustness axes (mbs_envs.envs.perturbed): the same perturbations as the sweep, one per episode."""

import json

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.envs.perturbed import TRAINING_AXES, PerturbedVectorEnv, TrainingPerturbations
from mbs_envs.studies.robustness import Perturbation, run

ENV = "mbs_envs/Acrobot-v1"
STEPS = 150
#: pulses that fit in a short episode (0.3 s at 2 ms)
SHORT_PULSES = {"per_joint": 1, "min_spacing": 0.05, "sigma": (0.01, 0.02), "amplitude": (0.5, 5.0)}


def plain(n, steps=STEPS):
    return gym.make_vec(ENV, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                        max_episode_steps=steps, preset="dfki_c1")  # fmt: skip


class Feedback:
    """A deterministic feedback law on what it sees (so that a delay or a lag changes the episode)."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(obs, float)
        return np.clip(0.8 * obs[:, 1:2] - 0.2 * obs[:, 4:5], -1, 1).astype(np.float32), state


def test_deterministic_axes_give_the_sweeps_episodes_bit_for_bit():
    """Members drawing nominal, a lag, a delay or pulses: each episode is robustness.run's with the same settings, to
    the bit (the arithmetic is shared); the perturbations reach the plant (the episodes differ from the nominal one)."""
    n = 24
    p = TrainingPerturbations(torque_response=(0.1, 0.9), time_delay=(0.004, 0.03), pulses=SHORT_PULSES)
    env = PerturbedVectorEnv(plain(n), p, seed=3)
    seen, _ = env.reset(seed=list(range(n)))
    axes = [p.axes[a] for a in env.axis]
    assert set(axes) == {"nominal", "torque response", "time delay", "perturbations"}  # each drawn by some member
    policy = Feedback()
    for _ in range(STEPS):
        seen, *_ = env.step(policy.predict(seen)[0])
    q, v = env.unwrapped.q, env.unwrapped.v
    lag = np.where([a == "torque response" for a in axes], env.value, 1.0)
    ref = run(
        plain(n),
        Feedback(),
        list(range(n)),
        Perturbation(response=lag, delay=env.delay.copy(), pulses=env.pulses.copy()),
    )
    np.testing.assert_array_equal(q, ref["q"])
    np.testing.assert_array_equal(v, ref["v"])
    nominal = run(plain(n), Feedback(), list(range(n)), Perturbation())
    for i, a in enumerate(axes):
        assert (a == "nominal") == np.array_equal(q[i], nominal["q"][i]), (i, a)
    assert (env.delay[[a == "time delay" for a in axes]] >= 2).all() and (
        env.delay[[a != "time delay" for a in axes]] == 0
    ).all()


def test_noise_reaches_only_its_entries_and_has_its_spread():
    n = 64
    p = TrainingPerturbations(velocity_noise=(0.3, 0.3), noise_index=(4, 5), torque_noise=(0.5, 0.5))
    env = PerturbedVectorEnv(plain(n, 400), p, seed=0)
    seen, _ = env.reset(seed=list(range(n)))
    noisy_obs = env.axis == p.axes.index("velocity noise")
    assert 0 < noisy_obs.sum() < n
    diffs = []
    for _ in range(400):
        true = env.history[env.k[0] % len(env.history)]
        diffs.append(seen - true)
        seen, *_ = env.step(np.zeros((n, 1), np.float32))
    d = np.array(diffs)  # (steps, n, 6)
    assert (d[:, :, :4] == 0).all() and (d[:, ~noisy_obs] == 0).all()
    sd = d[:, noisy_obs][:, :, 4:].std()
    assert abs(sd - 0.3) < 0.3 * 5 / np.sqrt(
        d[:, noisy_obs][:, :, 4:].size
    )  # 5 standard errors of a std estimate (~1/sqrt(2N))


def test_a_member_reset_by_mask_draws_afresh_and_the_others_keep_theirs():
    n = 12
    env = PerturbedVectorEnv(
        plain(n, 20), TrainingPerturbations(torque_response=(0.1, 2.0), time_delay=(0.0, 0.04)), seed=1
    )
    env.reset(seed=list(range(n)))
    for _ in range(5):
        env.step(np.full((n, 1), 0.2, np.float32))
    before = (env.axis.copy(), env.value.copy(), env.k.copy())
    mask = np.zeros(n, bool)
    mask[[2, 7]] = True
    env.reset(options={"reset_mask": mask})
    assert (env.k[mask] == 0).all() and (env.k[~mask] == before[2][~mask]).all()
    np.testing.assert_array_equal(env.axis[~mask], before[0][~mask])
    np.testing.assert_array_equal(env.value[~mask], before[1][~mask])
    assert not np.array_equal(env.value[mask], before[1][mask])


def test_the_same_seed_gives_the_same_draws_and_another_seed_others():
    def draws(seed):
        env = PerturbedVectorEnv(plain(16, 4000), "dfki", seed=seed)
        env.reset(seed=list(range(16)))
        return env.axis.copy(), env.value.copy(), env.pulses.copy()

    a, b, c = draws(5), draws(5), draws(6)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[1], c[1])


def test_dfki_ranges_are_the_benchmarks():
    from mbs_envs.studies import dfki

    p = TrainingPerturbations.dfki()
    assert p.axes == TRAINING_AXES
    assert p.velocity_noise == dfki.RANGES["velocity noise"] and p.time_delay == dfki.RANGES["time delay"]
    assert p.torque_noise == dfki.RANGES["torque noise"] and p.torque_response == dfki.RANGES["torque response"]
    assert p.pulses["amplitude"] == dfki.PULSES["amplitude"] and p.noise_index == (4, 5)
    again = TrainingPerturbations.of(json.loads(json.dumps(p.as_dict())))  # what config.json records reads back
    assert again == p


@pytest.mark.parametrize("spec, culprit", [
    ({"torque_noise": (-0.1, 0.5)}, "torque_noise"),
    ({"time_delay": (0.03, 0.01)}, "time_delay"),
    ({"torque_response": (0.0, 1.0)}, "torque_response"),
    ({"velocity_noise": "big"}, "velocity_noise"),
    ({"noise_index": (-1,)}, "noise_index"),
    ({"delay": (0, 1)}, "unknown"),
    ({"pulses": {"per_joint": 1}}, "pulses"),
    ("dfkj", "perturb"),
])  # fmt: skip
def test_bad_ranges_are_refused_by_name(spec, culprit):
    with pytest.raises(ValueError, match=culprit):
        TrainingPerturbations.of(spec)


def test_refusals_leave_the_env_and_its_generator_as_they_were():
    with pytest.raises(ValueError, match="Disabled"):
        PerturbedVectorEnv(
            gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point", preset="dfki_c1"), "dfki"
        )
    with pytest.raises(ValueError, match="noise_index"):
        PerturbedVectorEnv(plain(2), {"velocity_noise": (0, 1), "noise_index": (6,)})
    with pytest.raises(ValueError, match="pulses"):  # the benchmark's six pulses 1 s apart need 7 s
        PerturbedVectorEnv(plain(2, 3000), "dfki")
    env = PerturbedVectorEnv(plain(4, 3500), TrainingPerturbations.dfki(), seed=0)
    env.reset(seed=[0, 1, 2, 3])
    env.step(np.full((4, 1), 0.1, np.float32))
    state = (
        env.rng.bit_generator.state,
        env.k.copy(),
        env.applied.copy(),
        env.unwrapped.q,
        env.unwrapped.v,
        env.history.copy(),
    )
    for bad in (np.full((4, 1), np.nan, np.float32), np.zeros((3, 1), np.float32), np.zeros((4, 2))):
        with pytest.raises(ValueError, match="actions"):
            env.step(bad)
    with pytest.raises(ValueError):
        env.reset(options={"reset_mask": [True]})
    after = (env.rng.bit_generator.state, env.k, env.applied, env.unwrapped.q, env.unwrapped.v, env.history)
    assert state[0] == after[0]
    for x, y in zip(state[1:], after[1:]):
        np.testing.assert_array_equal(x, y)


def test_sb3_trains_behind_it_and_config_records_the_ranges(tmp_path):
    """train.py --perturb dfki: a PPO run through the adapter (action repeat 1 and 10: episodes end and restart with
    fresh draws) and config.json records the ranges that load back."""
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    short = {**TrainingPerturbations.dfki().as_dict(), "pulses": SHORT_PULSES}
    for k in (1, 10):
        venv = make_sb3_vec_env(
            ENV, n_envs=4, seed=0, action_repeat=k, perturb=short, preset="dfki_c1", max_episode_steps=80
        )
        venv.reset()
        ends = 0
        for _ in range(170 // k + 2):
            venv.step_async(np.zeros((4, 1), np.float32))
            obs, reward, done, infos = venv.step_wait()
            ends += done.sum()
            assert np.isfinite(obs).all()
        assert ends >= 4
    from tests.test_scripts import load_script

    script = load_script("train.py")
    script["run"](script["parse_args"](["--env", ENV, "--env-kwargs", '{"preset": "dfki_c1", "max_episode_steps": 80}', "--algo", "ppo",
                                        "--steps", "2048", "--n-envs", "4", "--action-repeat", "2", "--hyper", "n_steps=64",
                                        "--perturb", json.dumps(short), "--out", str(tmp_path)]))  # fmt: skip
    cfg = json.loads((tmp_path / "config.json").read_text())
    assert TrainingPerturbations.of(cfg["perturb"]) == TrainingPerturbations.of(short)


def test_the_module_docstrings_example_runs_as_written():
    import textwrap

    import mbs_envs.envs.perturbed as module

    doc = module.__doc__
    block = doc.split("observation.\n\n", 1)[1].split("\n\nThe wrapped env", 1)[0]
    namespace: dict = {}
    exec(textwrap.dedent(block), namespace)  # noqa: S102 - our own docstring
    assert namespace["venv"].reset().shape == (16, 6)
