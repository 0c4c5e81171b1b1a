"""The batched vector envs: equal to single envs (with autoresets), Gymnasium and SB3 semantics."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import scipy.linalg
import pytest
from gymnasium.vector import AutoresetMode

import mbs_envs
from mbs_envs.envs.vector import MBSVectorEnv

IDS = list(mbs_envs.ENV_IDS)
SMALL = {"mbs_envs/SerialChain-v0": {"n_links": 4}}
EPISODE = 40  # short episodes, so 200 steps include several autoresets per member


def make_pair(env_id, n, mode=AutoresetMode.NEXT_STEP, **kw):
    kw = {**SMALL.get(env_id, {}), **kw}
    venv = gym.make_vec(
        env_id,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        max_episode_steps=EPISODE,
        autoreset_mode=mode,
        **kw,
    )
    singles = [gym.make(env_id, max_episode_steps=EPISODE, **kw) for _ in range(n)]
    return venv, singles


@pytest.mark.parametrize("env_id", IDS)
def test_vector_env_equals_single_envs_over_200_steps_with_autoresets(env_id):
    n = 3
    venv, singles = make_pair(env_id, n)
    assert isinstance(venv.unwrapped, MBSVectorEnv)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, _ = venv.reset(seed=11)
    np.testing.assert_allclose(
        obs, np.stack([e.reset(seed=11 + i)[0] for i, e in enumerate(singles)]), rtol=0, atol=1e-12
    )
    rng = np.random.default_rng(0)
    done = np.zeros(n, bool)
    resets = 0
    for _ in range(200):
        a = rng.uniform(-1.2, 1.2, venv.action_space.shape)  # includes saturated actions
        obs, r, term, trunc, info = venv.step(a)
        for i, e in enumerate(singles):
            if done[i]:  # NEXT_STEP: this step resets the member and ignores its action
                o, _ = e.reset()
                ri, te, tr = 0.0, False, False
                resets += 1
            else:
                o, ri, te, tr, inf = e.step(a[i])
                assert inf["diverged"] == info["diverged"][i]
                np.testing.assert_allclose(info["energy"][i], inf["energy"], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(obs[i], o, rtol=0, atol=1e-12)
            assert r[i] == pytest.approx(ri, rel=1e-12, abs=1e-12)
            assert (term[i], trunc[i]) == (te, tr)
            done[i] = te or tr
    assert resets >= n * 3


@pytest.mark.parametrize("env_id", IDS)
def test_full_info_false_steps_alike_and_leaves_out_only_the_info(env_id):
    """``full_info=False`` (the SB3 adapter's setting; the compiled step then skips the energy) gives
    the very same observations, rewards, ends and divergence flags as ``full_info=True``."""
    kw = dict(num_envs=4, vectorization_mode="vector_entry_point", max_episode_steps=EPISODE, **SMALL.get(env_id, {}))
    full, lean = gym.make_vec(env_id, **kw), gym.make_vec(env_id, full_info=False, **kw)
    o1, _ = full.reset(seed=5)
    o2, _ = lean.reset(seed=5)
    np.testing.assert_array_equal(o1, o2)
    rng = np.random.default_rng(1)
    for _ in range(60):
        a = rng.uniform(-1.2, 1.2, full.action_space.shape)
        s1, s2 = full.step(a), lean.step(a)
        for x1, x2 in zip(s1[:4], s2[:4]):
            np.testing.assert_array_equal(x1, x2)
        np.testing.assert_array_equal(s1[4]["diverged"], s2[4]["diverged"])
        assert "energy" in s1[4] and "energy" not in s2[4]
        assert np.all(np.isfinite(s1[4]["energy"]))


@pytest.mark.parametrize("env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/RollingDisk-v0"])
def test_same_step_autoreset_reports_the_final_observation(env_id):
    venv, singles = make_pair(env_id, 2, AutoresetMode.SAME_STEP)
    venv.reset(seed=3)
    for i, e in enumerate(singles):
        e.reset(seed=3 + i)
    a = np.zeros(venv.action_space.shape)
    for k in range(EPISODE):
        obs, r, term, trunc, info = venv.step(a)
        last = [e.step(a[i]) for i, e in enumerate(singles)]
    assert np.all(term | trunc)
    for i, e in enumerate(singles):
        np.testing.assert_allclose(info["final_obs"][i], last[i][0], atol=1e-12)
        np.testing.assert_allclose(obs[i], e.reset()[0], atol=1e-12)  # already the next episode's start


def test_bad_actions_raise_and_change_nothing():
    venv = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=4, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    q = venv.unwrapped.q
    bad = np.zeros((4, 2))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"members \[2\]"):
        venv.step(bad)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((3, 2)))
    np.testing.assert_array_equal(venv.unwrapped.q, q)


def test_a_diverging_member_does_not_disturb_the_others():
    venv, singles = make_pair("mbs_envs/Planar2R-v0", 3, params={"b1": 400.0, "b2": 400.0})
    venv.reset(seed=5)
    for i, e in enumerate(singles):
        e.reset(seed=5 + i)
    # member 1 restarts with an absurd speed: RK4 blows up on it (stiff friction)
    wild = {"q": [0.0, 0.0], "v": [1e6, -1e6]}
    venv.reset(options={**wild, "reset_mask": np.array([False, True, False])})
    singles[1].reset(options=wild)
    a = np.zeros((3, 2))
    obs, r, term, trunc, info = venv.step(a)
    outs = [e.step(a[i]) for i, e in enumerate(singles)]
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(r))
    assert info["diverged"].tolist() == [False, True, False] and term.tolist() == [False, True, False]
    for i in range(3):
        np.testing.assert_allclose(obs[i], outs[i][0], atol=1e-12)
        assert info["diverged"][i] == outs[i][4]["diverged"]


def test_domain_randomization_draws_members_parameters_from_their_seeds():
    kw = {"randomize": {"m2": 0.3, "l1": 0.2}}
    venv = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=4, vectorization_mode="vector_entry_point", **kw)
    venv.reset(seed=1)
    model = venv.unwrapped.model
    m2, l1 = model.params.m2, model.params.l1
    assert m2.shape == (4,) and np.all(np.abs(m2 / 1.0 - 1) <= 0.3 + 1e-12) and np.unique(m2).size == 4
    # reproducible from the seed, and the batch's dynamics are each member's own
    venv2 = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=4, vectorization_mode="vector_entry_point", **kw)
    venv2.reset(seed=1)
    np.testing.assert_array_equal(venv2.unwrapped.model.params.m2, m2)
    q, v, u = venv.unwrapped.q, venv.unwrapped.v, np.ones((4, 2))
    a = model.forward_dynamics(q, v, u)
    nominal = venv.unwrapped.nominal_model
    for i in range(4):
        single = type(nominal)(nominal.params.replace(m2=float(m2[i]), l1=float(l1[i])))
        np.testing.assert_allclose(a[i], single.forward_dynamics(q[i], v[i], u[i]), rtol=1e-13)
    with pytest.raises(ValueError, match="per-member"):
        gym.make_vec("mbs_envs/FourBar-v0", num_envs=2, vectorization_mode="vector_entry_point", randomize={"m2": 0.1})
    with pytest.raises(ValueError, match="unknown parameter"):
        gym.make_vec(
            "mbs_envs/Planar2R-v0", num_envs=2, vectorization_mode="vector_entry_point", randomize={"mass": 0.1}
        )


def test_domain_randomization_over_a_range_draws_the_parameter_itself():
    """``randomize={"b2": (low, high)}``: each member's b2 from U(low, high) at every reset (a damping whose nominal
    value is 0 cannot be scaled), with scaled ones beside it; bad ranges are refused by name and leave nothing made."""
    kw = {"randomize": {"b2": (0.0, 0.1), "m2": 0.25}}
    venv = gym.make_vec("mbs_envs/AcrobotDFKI-v1", num_envs=64, vectorization_mode="vector_entry_point", **kw)
    assert np.all(venv.unwrapped.model.params.b2 == 0.0)  # nominal until the first reset
    venv.reset(seed=3)
    b2, m2 = venv.unwrapped.model.params.b2, venv.unwrapped.model.params.m2
    nominal = venv.unwrapped.nominal_params
    assert b2.shape == (64,) and np.all((b2 >= 0.0) & (b2 < 0.1)) and b2.std() > 0.02  # U(0, 0.1): std 0.029
    assert np.all(np.abs(m2 / nominal.m2 - 1) <= 0.25 + 1e-12) and not np.allclose(m2, nominal.m2)
    # each member's own draw from its seed (member i seeded 3 + i), the dynamics each member's own
    one = gym.make_vec("mbs_envs/AcrobotDFKI-v1", num_envs=1, vectorization_mode="vector_entry_point", **kw)
    one.reset(seed=5)
    assert one.unwrapped.model.params.b2[0] == b2[2] and one.unwrapped.model.params.m2[0] == m2[2]
    q, v, u = venv.unwrapped.q, np.ones((64, 2)), np.zeros((64, 1))
    a = venv.unwrapped.model.forward_dynamics(q, v, u)
    model = venv.unwrapped.nominal_model
    single = model.with_params(nominal.replace(b2=float(b2[7]), m2=float(m2[7])))
    np.testing.assert_allclose(a[7], single.forward_dynamics(q[7], v[7], u[7]), rtol=1e-13)
    venv.reset(seed=4)
    assert not np.array_equal(venv.unwrapped.model.params.b2, b2)  # drawn again at the reset
    for bad, match in (((0.1, 0.0), "low <= high"), ((0.0,), "range"), ((-1.0, 0.1), "b2"), ((0.0, np.nan), "finite")):
        with pytest.raises(ValueError, match=match):
            gym.make_vec(
                "mbs_envs/AcrobotDFKI-v1", num_envs=2, vectorization_mode="vector_entry_point", randomize={"b2": bad}
            )


def test_reset_mask_and_seed_lists():
    venv = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=3, vectorization_mode="vector_entry_point")
    obs0, _ = venv.reset(seed=[4, 5, 6])
    obs1, _ = venv.reset(seed=[None, 5, None], options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(obs1, obs0)  # member 1 re-seeded identically, others untouched
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": np.ones(2, bool)})


def test_sb3_adapter_trains_ppo_for_a_few_updates():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env  # noqa: F401  (single-env checker; VecEnv below)

    from mbs_envs.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mbs_envs/Planar2R-v0", n_envs=8, seed=0, max_episode_steps=50)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=128, n_epochs=2, seed=0, device="cpu")
    model.learn(3 * 64 * 8)
    assert model.num_timesteps == 3 * 64 * 8
    # episodes ended and were reported the SB3 way
    assert len(model.ep_info_buffer) >= 8
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    obs, rewards, dones, infos = venv.step(action)
    assert obs.shape == (8, 12) and rewards.dtype == np.float32 and len(infos) == 8


def test_sb3_adapter_reports_terminal_observations():
    pytest.importorskip("stable_baselines3")
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mbs_envs/Planar2R-v0", n_envs=2, seed=0, monitor=False, max_episode_steps=5)
    venv.reset()
    for _ in range(5):
        obs, rewards, dones, infos = venv.step(np.zeros((2, 2)))
    assert dones.all()
    for info in infos:
        assert info["terminal_observation"].shape == (12,) and info["TimeLimit.truncated"]


@pytest.mark.parametrize("env_id", ["mbs_envs/FourBar-v0", "mbs_envs/RollingDisk-v0"])
def test_batched_rollout_scores_like_single_rollouts(env_id):
    """rollout_batch on the vector env gives the episodes rollout gives on single envs."""
    from mbs_envs.controllers import LQR, ComputedTorque
    from mbs_envs.studies.evaluation import episode_metrics, rollout, rollout_batch

    env = gym.make(env_id, max_episode_steps=60)
    policy = (LQR if "Disk" in env_id else ComputedTorque)(env)
    venv = gym.make_vec(
        env_id, num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled", max_episode_steps=60
    )
    batch = rollout_batch(venv, policy, [3, 4])
    for ep_b, seed in zip(batch, [3, 4]):
        ep = rollout(env, policy, seed)
        assert len(ep.t) == len(ep_b.t) == 60
        # measured difference 0 here; the margin is for the controllers' batched linear
        # algebra (pinv, LQR gains), which another BLAS may round differently from single calls
        np.testing.assert_allclose(ep_b.tracking_error, ep.tracking_error, atol=1e-11)
        np.testing.assert_allclose(ep_b.u, ep.u, atol=1e-11)
        m, mb = episode_metrics(ep), episode_metrics(ep_b)
        assert mb["rms_error"] == pytest.approx(m["rms_error"], rel=1e-11)


def test_rgb_array_render_gives_one_frame_per_member():
    venv = gym.make_vec(
        "mbs_envs/RollingDisk-v0", num_envs=2, vectorization_mode="vector_entry_point", render_mode="rgb_array"
    )
    venv.reset(seed=0)
    frames = venv.render()
    assert len(frames) == 2 and frames[0].ndim == 3 and frames[0].shape[-1] == 3
    assert not np.array_equal(frames[0], frames[1])  # different members, different pictures


def test_sb3_action_repeat_holds_each_action_k_steps_with_exact_episode_ends():
    """An action held K steps by the adapter = K steps of single envs with that action: rewards
    summed up to each member's own end, the terminal observation at that end, the steps past it
    discarded and the next episode started from the member's generator. Episodes of 10 steps
    and K = 4, so ends fall inside a repeat; member 0 is restarted one decision late, so it
    ends while the others run on (and the reverse)."""
    pytest.importorskip("stable_baselines3")
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    env_id, n, K = "mbs_envs/Acrobot-v0", 3, 4
    singles = [gym.make(env_id, max_episode_steps=10) for _ in range(n)]
    venv = make_sb3_vec_env(env_id, n_envs=n, seed=7, monitor=False, action_repeat=K, max_episode_steps=10)
    obs = venv.reset()
    for i, env in enumerate(singles):
        np.testing.assert_array_equal(obs[i], env.reset(seed=7 + i)[0])
    rng = np.random.default_rng(0)
    ended = set()
    for decision in range(9):
        if decision == 1:  # restart member 0 mid-episode in both
            venv.venv.reset(options={"reset_mask": np.array([True, False, False])})
            singles[0].reset()
        a = rng.uniform(-1, 1, (n, 1))
        obs, reward, dones, infos = venv.step(a)
        for i, env in enumerate(singles):
            total = 0.0
            for k in range(K):
                o, r, term, trunc, _ = env.step(a[i])
                total += r
                if term or trunc:
                    break
            assert dones[i] == (term or trunc)
            assert reward[i] == pytest.approx(total, rel=1e-6)  # float32 rewards (SB3's)
            if dones[i]:
                ended.add((i, decision, k))
                np.testing.assert_allclose(infos[i]["terminal_observation"], o, rtol=0, atol=1e-12)
                assert infos[i]["TimeLimit.truncated"] and not infos[i]["diverged"]
                o, _ = env.reset()
            np.testing.assert_allclose(obs[i], o, rtol=0, atol=1e-12)
    by_decision = {d: {i for i, dd, _ in ended if dd == d} for _, d, _ in ended}
    assert any(0 < len(m) < n for m in by_decision.values())  # some members ended while others ran on
    assert all(k == 1 for _, _, k in ended)  # inside the repeat (on its 2nd step), not at its end
    for bad in (0, -1, 2.0, True):
        with pytest.raises(ValueError, match="action_repeat"):
            make_sb3_vec_env(env_id, n_envs=2, action_repeat=bad)


def test_held_policy_decides_every_k_calls_per_member_and_restarts_with_episodes():
    from mbs_envs.studies.held import HeldPolicy

    class Counter:  # returns how many times it was asked, per member
        calls = 0

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            Counter.calls += 1
            return np.full((np.atleast_2d(obs).shape[0], 1), float(Counter.calls)).squeeze(0) if np.ndim(
                obs
            ) == 1 else np.full((len(obs), 1), float(Counter.calls)), None

    policy, state, seen = HeldPolicy(Counter(), 3), None, []
    for k in range(7):
        start = np.array([k == 0, k == 4])  # member 1 starts a new episode at call 4
        action, state = policy.predict(np.zeros((2, 5)), state=state, episode_start=start)
        seen.append(action[:, 0].tolist())
    # member 0 decides at calls 0, 3, 6; member 1 at 0, 3, then 4 (new episode), then 7
    assert seen == [[1, 1], [1, 1], [1, 1], [2, 2], [2, 3], [2, 3], [4, 3]]
    one = HeldPolicy(Counter(), 2)
    a0, s = one.predict(np.zeros(5))
    a1, s = one.predict(np.zeros(5), state=s)
    a2, s = one.predict(np.zeros(5), state=s)
    assert a0.shape == (1,) and a1 == a0 and a2 != a0
    with pytest.raises(ValueError, match="action_repeat"):
        HeldPolicy(Counter(), 0)


@pytest.mark.parametrize("compiled", [True, False])
def test_the_state_is_one_array_of_columns_on_both_paths_and_observations_are_column_major(compiled):
    """The vector env keeps its state as columns ``(n, num_envs)`` (the compiled step's layout, advanced
    in place) with its rows as views of them; the numpy path writes into the same arrays. Both paths
    return observations column-major (the task kernels write one column per member), as Gymnasium's own
    ``CartPoleVectorEnv`` does."""
    venv = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=5, vectorization_mode="vector_entry_point", compiled=compiled)
    env = venv.unwrapped
    venv.reset(seed=2)
    rng = np.random.default_rng(3)
    for _ in range(3):
        obs, *_ = venv.step(rng.uniform(-1, 1, venv.action_space.shape))
    for rows, cols in ((env._q, env._qc), (env._v, env._vc)):
        assert cols.flags.c_contiguous and cols.shape == (2, 5) and np.shares_memory(rows, cols)
        np.testing.assert_array_equal(rows, cols.T)
    np.testing.assert_array_equal(env.q, env._qc.T)
    assert obs.shape == (5, venv.single_observation_space.shape[0]) and obs.dtype == np.float32
    assert obs.flags.f_contiguous
    obs[1] = 0.0  # rows of the batch stay writable (autoresets write them)


def test_member_params_run_each_member_on_its_own_plant():
    """A parameter sweep as one batch: member i equals the single env made with its params (1e-12)."""
    sets = [{"m2": 0.5}, {}, {"m2": 0.7, "I1": 0.02}, {"l1": 0.25, "r1": 0.1}]
    v = gym.make_vec("mbs_envs/AcrobotDFKI-v1", num_envs=4, vectorization_mode="vector_entry_point", member_params=sets)
    assert v.unwrapped.member_params == tuple(sets)
    obs, _ = v.reset(seed=0)
    a = np.linspace(-1, 1, 4, dtype=np.float32)[:, None]
    for _ in range(60):
        obs, r, *_ = v.step(a)
    for i, params in enumerate(sets):
        e = gym.make("mbs_envs/AcrobotDFKI-v1", params=params or None)
        e.reset(seed=i)
        for _ in range(60):
            o, ri, *_ = e.step(a[i])
        np.testing.assert_allclose(v.unwrapped.q[i], e.unwrapped.q, rtol=0, atol=1e-12)
        assert r[i] == pytest.approx(ri, rel=1e-12, abs=1e-12)


def test_member_params_with_randomize_scale_the_members_value():
    v = gym.make_vec("mbs_envs/Acrobot-v1", num_envs=2, vectorization_mode="vector_entry_point",
                     member_params=[{"m2": 2.0}, {}], randomize={"m2": 0.1})  # fmt: skip
    v.reset(seed=3)
    m2 = v.unwrapped.model.params.m2
    scales = v.unwrapped._scales["m2"]
    np.testing.assert_allclose(m2, [2.0 * scales[0], 1.0 * scales[1]], rtol=1e-15)


@pytest.mark.parametrize(
    "env_id, member_params, match",
    [
        ("mbs_envs/Acrobot-v1", [{"m2": -1.0}, {}], r"member_params\[0\]: parameter 'm2'"),
        ("mbs_envs/Acrobot-v1", [{"m2": 1.0}], "sequence of 2 mappings"),
        ("mbs_envs/Acrobot-v1", "m2", "sequence of 2 mappings"),
        ("mbs_envs/Acrobot-v1", [{"mass": 1.0}, {}], r"member_params\[0\]"),
        ("mbs_envs/SerialChain-v0", [{}, {}], "does not support per-member parameters"),
    ],
)
def test_member_params_are_refused_with_the_culprit_named(env_id, member_params, match):
    with pytest.raises(ValueError, match=match):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", member_params=member_params)


def test_apply_impulse_changes_momentum_by_the_impulse():
    """M(q) (v+ - v-) = J to round-off, per member with its own parameters; refusals change nothing."""
    v = gym.make_vec("mbs_envs/Acrobot-v1", num_envs=3, vectorization_mode="vector_entry_point",
                     member_params=[{"m2": 0.5}, {}, {"I2": 0.3}])  # fmt: skip
    base = v.unwrapped
    v.reset(seed=1)
    v.step(np.zeros((3, 1), np.float32))
    J = np.array([[0.3, -0.1], [0.0, 0.2], [-1.0, 1.0]])
    v0, q = base.v, base.q
    base.apply_impulse(J)
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", base.model.mass_matrix(q), base.v - v0), J, rtol=1e-12, atol=1e-14
    )
    before = base.v
    for bad in (J[:2], np.full((3, 2), np.nan), "x"):
        with pytest.raises(ValueError, match="J"):
            base.apply_impulse(bad)
    np.testing.assert_array_equal(base.v, before)


@pytest.mark.parametrize("env_id", ["mbs_envs/FourBar-v0", "mbs_envs/RollingDisk-v0"])
def test_apply_impulse_with_constraints_is_the_impulsive_equation_of_motion(env_id):
    """With constraints: M (v+ - v-) - J lies in the range of Psi^T (the constraints' impulse), Psi v+ = 0,
    and the kinetic energy of the change is the least among velocities that keep the constraints (the
    M-orthogonal projection of M^-1 J, checked against an independent null-space solve)."""
    v = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    base = v.unwrapped
    v.reset(seed=2)
    v.step(np.zeros((3, base.model.nu), np.float32))
    J = np.random.default_rng(0).normal(size=(3, base.model.nv))
    q, v0 = base.q, base.v
    base.apply_impulse(J)
    M, Psi = base.model.mass_matrix(q), base.model.constraint_jacobian(q)
    for i in range(3):
        N = scipy.linalg.null_space(Psi[i])  # velocities that keep the constraints: v = N z
        z = np.linalg.solve(N.T @ M[i] @ N, N.T @ (M[i] @ v0[i] + J[i]))  # Lagrange's equations on the null space
        np.testing.assert_allclose(base.v[i], N @ z, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Psi[i] @ base.v[i], 0.0, atol=1e-13)
