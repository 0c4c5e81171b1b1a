"""The comparison's fairness rules: seeds, failure scoring, confidence intervals, residual policies, tuning."""

from __future__ import annotations

import json
import os
import pathlib

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import ComputedTorque, tuned
from mbs_envs.studies import comparison as cmp
from mbs_envs.studies import seeds, tuning
from mbs_envs.studies.residual import ResidualPolicy, check_bound, combine

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_seed_ranges_are_disjoint():
    training = set()
    for run in range(0, 1000, 7):
        training |= set(seeds.training_members(run, 64))
    for block in (seeds.TEST, seeds.VALIDATION, seeds.TUNING):
        assert not training & set(block)
    assert not set(seeds.TEST) & set(seeds.VALIDATION) and not set(seeds.TEST) & set(seeds.TUNING)
    assert not set(seeds.training_members(0, 1000)) & set(seeds.training_members(1, 1000))  # runs apart too
    with pytest.raises(ValueError, match="n_envs"):
        seeds.training_members(0, 1001)
    with pytest.raises(ValueError, match="test"):
        seeds.test_seeds(10_001)


def test_shipped_agents_never_trained_or_validated_on_test_seeds():
    test = set(seeds.test_seeds(1000))
    configs = list((ROOT / "agents").rglob("config.json"))
    assert configs
    for path in configs:
        cfg = json.loads(path.read_text())
        lo, hi = cfg["training_member_seeds"]
        assert not set(range(lo, hi + 1)) & test, path
        lo, hi = cfg["validation_seeds"]
        assert not set(range(lo, hi + 1)) & test, path


def _rows(policy, kind, errors, failed, train_seed=0):
    return [{"policy": policy, "kind": kind, "train_seed": train_seed, "rms_error_settled": e, "max_error": e, "rms_torque": 1.0,
             "peak_torque": 1.0, "return": -e, "failed": f, "latency_us": 1.0, "latency_noisy_us": 1.0, "start_peak_torque": 1.0}
            for e, f in zip(errors, failed)]  # fmt: skip


def test_a_failing_policy_is_never_best_and_failures_never_lower_the_error():
    # the failing policy's failed episodes have tiny truncated errors: they must not count
    failing = cmp.summarize_policy(_rows("A", "RL", [1e-6] * 5 + [0.5] * 15, [True] * 5 + [False] * 15))
    steady = cmp.summarize_policy(_rows("B", "RL", [0.1] * 20, [False] * 20))
    assert failing["success"] == pytest.approx(0.75)
    assert failing["rms_error_settled"] == pytest.approx(0.5)  # successful episodes only
    assert cmp.best_policy({"A": failing, "B": steady}, "RL") == "B"
    # even when A's surviving episodes beat B's error
    better_but_failing = cmp.summarize_policy(_rows("A", "RL", [0.01] * 20, [True] + [False] * 19))
    assert better_but_failing["success"] == pytest.approx(0.95)
    assert cmp.best_policy({"A": better_but_failing, "B": steady}, "RL") == "A"  # 95 % is the stated threshold
    worse = cmp.summarize_policy(_rows("A", "RL", [0.01] * 20, [True, True] + [False] * 18))
    assert cmp.best_policy({"A": worse, "B": steady}, "RL") == "B"
    all_failed = cmp.summarize_policy(_rows("C", "RL", [0.0] * 4, [True] * 4))
    assert np.isnan(all_failed["rms_error_settled"]) and cmp.best_policy({"C": all_failed}, "RL") is None


def test_hierarchical_bootstrap():
    mean, lo, hi = cmp.hierarchical_bootstrap([np.full(10, 0.3)])
    assert mean == lo == hi == pytest.approx(0.3)
    rng = np.random.default_rng(1)
    groups = [rng.normal(1.0, 0.1, 20), rng.normal(2.0, 0.1, 20), rng.normal(3.0, 0.1, 20)]
    mean, lo, hi = cmp.hierarchical_bootstrap(groups)
    assert mean == pytest.approx(np.mean(np.concatenate(groups)))
    assert lo < mean < hi
    # the spread between training seeds widens the interval far beyond the episodes' own spread
    _, lo1, hi1 = cmp.hierarchical_bootstrap([np.concatenate(groups)])
    assert hi - lo > 3 * (hi1 - lo1)
    assert all(np.isnan(cmp.hierarchical_bootstrap([np.array([]), np.array([])])))


class _Fixed:
    """A stand-in correction policy returning fixed actions."""

    def __init__(self, action):
        self.action = np.asarray(action, np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.broadcast_to(self.action, np.shape(obs)[:-1] + self.action.shape[-1:]).copy(), None


def test_residual_with_zero_correction_is_the_base_controller():
    env = gym.make("mbs_envs/FourBar-v0")
    base = ComputedTorque(env)
    obs, _ = env.reset(seed=3)
    policy = ResidualPolicy(base, _Fixed([0.0]), 0.25)
    np.testing.assert_array_equal(policy.predict(obs)[0], base.predict(obs)[0])


@pytest.mark.parametrize("correction", [[5.0, -7.0], [1e30, -1e30], [0.3, 0.1], [-1.0, 1.0]])
def test_residual_correction_is_bounded(correction):
    env = gym.make("mbs_envs/Planar2R-v0")
    base = ComputedTorque(env)
    bound = 0.2
    policy = ResidualPolicy(base, _Fixed(correction), bound)
    rng = np.random.default_rng(0)
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        obs = obs + rng.normal(0, 0.1, obs.shape).astype(np.float32)
        a, a0 = policy.predict(obs)[0], base.predict(obs)[0]
        assert np.all(np.abs(a) <= 1.0)
        assert np.all(np.abs(a.astype(float) - a0) <= bound + 1e-6)


@pytest.mark.parametrize("bound", [0.0, -0.1, np.nan, 3.0, "x"])
def test_residual_bound_is_validated(bound):
    with pytest.raises(ValueError, match="bound"):
        check_bound(bound)


def test_residual_training_env_with_zero_correction_replays_the_base_controller():
    """The training wrapper applies base + correction: zero corrections give the base controller's episodes."""
    pytest.importorskip("stable_baselines3")
    from mbs_envs.studies.residual import residual_vec_env
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    env_id = "mbs_envs/FourBar-v0"
    base = ComputedTorque(gym.make(env_id))
    venv = residual_vec_env(make_sb3_vec_env(env_id, n_envs=2, seed=5, monitor=False), base, 0.25)
    obs = venv.reset()
    ref = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    ref_obs, _ = ref.reset(seed=[5, 6])
    np.testing.assert_array_equal(obs, ref_obs)
    for _ in range(20):
        obs, _, _, _ = venv.step(np.zeros((2, 1), np.float32))
        ref_obs, *_ = ref.step(base.predict(ref_obs)[0])
        np.testing.assert_array_equal(obs, ref_obs)
    a = combine(np.array([[0.9]]), np.array([[1.0]]), 0.25)
    assert a[0, 0] == 1.0  # saturates at the actuator limit


def test_tuning_returns_gains_no_worse_than_the_old_defaults_on_its_own_seeds():
    """The procedure on a short budget (3 tuning seeds, 2 s episodes): its pick scores at least as well as
    the pre-tuning default (10 rad/s, critical damping, which is not on the grid) on the same seeds."""
    for name in ("computed torque", "PD"):
        best, rows = tuning.tune("Planar2R", name, n_seeds=3, max_episode_steps=200)
        assert len(rows) == len(tuning.joint_grid()) and best in [r["entry"] for r in rows]
        chosen = next(r for r in rows if r["entry"] == best)
        old = tuning.score("Planar2R", name, tuned.FALLBACK[name], tuning.tuning_seeds(3), max_episode_steps=200)
        assert (chosen["failure_rate"], chosen["error"]) <= old.key[:2]
        assert best != tuned.FALLBACK[name]


def test_tuning_ranks_candidates_with_an_unwon_condition_by_the_conditions_they_win():
    nan = float("nan")
    won_all = tuning.Score(0.5, 9.0, {"nominal": 8.0, "-20%": 10.0})
    fast = tuning.Score(0.5, nan, {"nominal": 6.0, "-20%": nan})
    slow = tuning.Score(0.5, nan, {"nominal": 7.0, "-20%": nan})
    none = tuning.Score(0.5, nan, {"nominal": nan, "-20%": nan})
    fewer_failures = tuning.Score(0.4, nan, {"nominal": 12.0, "-20%": nan})
    ranked = sorted([none, slow, won_all, fast, fewer_failures], key=lambda sc: sc.key)
    assert ranked == [fewer_failures, won_all, fast, slow, none]


def test_controllers_default_to_the_tuned_gains():
    record = json.loads(tuned.PATH.read_text())
    for env_id, by_controller in record["gains"].items():
        env = gym.make(env_id)
        for name, entry in by_controller.items():
            if name.endswith(
                " (robust catch)"
            ):  # a catch tuned for robustness: read by scripts/dfki.py --robust-catch only
                assert tuned.stored_entry(env_id, name) == entry and set(entry) <= {"lqr_r", "catch", "release"}
                continue
            assert tuned.tuned_gains(env, name) == entry
        if "computed torque" in by_controller:
            w, z = by_controller["computed torque"]["omega"], by_controller["computed torque"]["zeta"]
            ct = ComputedTorque(env)
            np.testing.assert_allclose(ct.kp, w**2, rtol=1e-15)
            np.testing.assert_allclose(ct.kd, 2 * z * w, rtol=1e-15)


def test_the_headline_never_calls_a_policy_beaten_when_it_wins_on_return():
    from mbs_envs.studies.comparison import verdict_against

    pd = {"success": 1.0, "rms_error_settled": 0.01, "return": -5.0}
    assert (
        verdict_against({"success": 1.0, "rms_error_settled": 0.03, "return": -0.9}, pd)
        == "beats PD on return, not on settled error"
    )
    assert (
        verdict_against({"success": 1.0, "rms_error_settled": 0.005, "return": -9.0}, pd)
        == "beats PD on settled error, not on return"
    )
    assert verdict_against({"success": 1.0, "rms_error_settled": 0.005, "return": -1.0}, pd) == "beats PD"
    assert verdict_against({"success": 1.0, "rms_error_settled": 0.03, "return": -9.0}, pd) == "does not beat PD"
    # a failed episode never improves a score: lower success loses on both, whatever the numbers
    assert verdict_against({"success": 0.95, "rms_error_settled": 1e-9, "return": 1e9}, pd) == "does not beat PD"
    assert (
        verdict_against({"success": 1.0, "rms_error_settled": 0.01, "return": -5.0}, pd) == "does not beat PD"
    )  # ties win nothing


def test_obs_normalization_is_vecnormalize_s_and_survives_saving(tmp_path):
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from mbs_envs.studies.normalized import NormalizedPolicy, ObsNormalization

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("mbs_envs/Acrobot-v1")] * 2), gamma=0.99)
    venv.reset()
    for _ in range(50):
        venv.step(np.random.default_rng(0).uniform(-1, 1, (2, 1)).astype(np.float32))
    norm = ObsNormalization.of(venv)
    obs = np.random.default_rng(1).normal(size=(5, 6)).astype(np.float32) * 5
    np.testing.assert_allclose(norm(obs), venv.normalize_obs(obs), rtol=1e-6, atol=1e-6)
    norm.save(tmp_path)
    again = ObsNormalization.load(tmp_path)
    np.testing.assert_array_equal(again(obs), norm(obs))

    class Echo:
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return observation, state

    np.testing.assert_array_equal(NormalizedPolicy(Echo(), again).predict(obs)[0], norm(obs))


def test_swing_up_agents_also_run_as_rl_plus_lqr_on_the_model_based_plus_rl_side(tmp_path):
    from mbs_envs.studies.comparison import HAND_OVER, SCENES, find_agents, kind_of

    for scene in ("Acrobot", "Planar2R"):
        for k in (0, 1):
            folder = tmp_path / SCENES[scene][0].split("/")[-1] / "ppo" / f"seed{k}"
            folder.mkdir(parents=True)
            (folder / "agent.zip").write_bytes(b"")
    swing, track = find_agents(tmp_path, "Acrobot"), find_agents(tmp_path, "Planar2R")
    assert sorted(swing) == ["PPO", "PPO + LQR"] and sorted(track) == ["PPO"]
    assert swing["PPO + LQR"] == [HAND_OVER + p for p in swing["PPO"]] and len(swing["PPO"]) == 2
    assert (kind_of("PPO"), kind_of("PPO + LQR"), kind_of("residual PPO")) == (
        "RL",
        "model-based + RL",
        "model-based + RL",
    )
    # agents of a later version of the task (another reward, the same plant and success rule) join, named with it;
    # earlier versions' do not
    for version in ("v2", "v0"):
        folder = tmp_path / f"Acrobot-{version}" / "sac" / "seed0"
        folder.mkdir(parents=True)
        (folder / "agent.zip").write_bytes(b"")
    swing = find_agents(tmp_path, "Acrobot")
    assert sorted(swing) == ["PPO", "PPO + LQR", "SAC (v2 reward)", "SAC (v2 reward) + LQR"]
    assert swing["SAC (v2 reward)"] == [str(tmp_path / "Acrobot-v2" / "sac" / "seed0")]
    assert (kind_of("SAC (v2 reward)"), kind_of("SAC (v2 reward) + LQR")) == ("RL", "model-based + RL")


def test_a_reward_only_version_takes_its_plants_tuned_gains_even_with_entries_of_its_own():
    from mbs_envs.controllers import tuned

    v0, v1, v2 = gym.make("mbs_envs/Acrobot-v0"), gym.make("mbs_envs/Acrobot-v1"), gym.make("mbs_envs/Acrobot-v2")
    assert (
        tuned.tuned_gains(v2, "swing-up + LQR")
        == tuned.tuned_gains(v1, "swing-up + LQR")
        == tuned.tuned_gains(v0, "swing-up + LQR")
        != tuned.FALLBACK["swing-up + LQR"]
    )
    assert (
        "mbs_envs/Acrobot-v1" in tuned._table()
    )  # it has an entry (the RL + LQR catch), and still falls back per controller


def test_the_run_records_what_its_numbers_depend_on():
    from mbs_envs.studies import provenance

    rec = provenance.record()
    assert set(rec) == {"python", "platform", "cpu", "libraries", "pinned"} and set(rec["libraries"]) == set(
        provenance.LIBRARIES
    )
    import numpy

    assert rec["libraries"]["numpy"] == numpy.__version__ and f"numpy {numpy.__version__}" in provenance.summary_line(
        rec
    )
    assert set(rec["cpu"]["flags"]) <= set(provenance.CPU_FLAGS)
    assert set(rec["pinned"]) == set(provenance.PINNED)


def test_a_recorded_command_pastes_back_into_a_shell_as_it_was_given(monkeypatch):
    """A JSON argument (spaces, quotes, brackets) survives: the recorded line split as a POSIX shell splits it is the
    process's arguments; another script's process records nothing."""
    import shlex
    import sys

    from mbs_envs.studies.provenance import command_line

    argv = ["scripts/train.py", "--env-kwargs", '{"reward_weights": [5, 0.4, 400]}', "--out", "runs/a b", "--seed", "0"]
    monkeypatch.setattr(sys, "argv", argv)
    line = command_line("train.py")
    assert line.startswith("python scripts/train.py ") and shlex.split(line)[2:] == argv[1:]
    assert command_line("dfki.py") is None
    monkeypatch.setattr(sys, "argv", ["scripts/dfki.py"])
    assert command_line("dfki.py") == "python scripts/dfki.py"


def test_the_evaluation_scripts_pin_mkl_before_torch_loads_and_keep_what_the_user_set():
    """issue 37: the agents' actions differed in their last bits between MKL's AVX-512 and AVX2 code (96 of 450 summary
    values of two scenes); the scripts pin MKL's reproducible mode, in a fresh process before torch is imported."""
    import subprocess
    import sys

    from mbs_envs.studies import provenance

    code = (
        "import os, sys\n"
        "from mbs_envs.studies import provenance\n"
        "print(provenance.pin_numerics())\n"
        "import torch\n"
        "print(os.environ['MKL_CBWR'], os.environ['ATEN_CPU_CAPABILITY'])\n"
        "print(provenance.summary_line(provenance.record()))\n"
        "try:\n"
        "    provenance.pin_numerics()\n"
        "except RuntimeError as e:\n"
        "    print('refused:', e)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in provenance.PINNED}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert out[0] == str(provenance.PINNED) and out[1] == "COMPATIBLE avx2"
    assert "MKL_CBWR=COMPATIBLE" in out[2] and out[3].startswith("refused: pin_numerics() must run before torch")
    env["MKL_CBWR"] = "AVX2"  # a user's own choice stays
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert out[1] == "AVX2 avx2"
