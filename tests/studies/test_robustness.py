"""Robustness sweeps (mbs_envs.studies.robustness) and the DFKI robustness benchmark's axes (studies.dfki)."""

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.envs import presets
from mbs_envs.studies import dfki
from mbs_envs.studies.robustness import Perturbation, gaussian_pulses, run

ENV = "mbs_envs/Acrobot-v1"


def venv(n, steps=40, **kw):
    return gym.make_vec(
        ENV,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        autoreset_mode="Disabled",
        max_episode_steps=steps,
        **kw,
    )


class Recorder:
    """A policy that pushes with a fixed action and remembers every observation it saw."""

    def __init__(self, action=0.3):
        self.seen, self.action = [], action

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.seen.append(np.array(obs))
        return np.full((len(obs), 1), self.action, np.float32), state


def plain_final(n, action=0.3, steps=40):
    v = venv(n, steps)
    v.reset(seed=list(range(n)))
    for _ in range(steps):
        v.step(np.full((n, 1), action, np.float32))
    return v.unwrapped.q, v.unwrapped.v


def test_unperturbed_run_is_the_plain_rollout():
    res = run(venv(3), Recorder(), [0, 1, 2], Perturbation())
    q, v = plain_final(3)
    np.testing.assert_array_equal(res["q"], q)
    np.testing.assert_array_equal(res["v"], v)
    assert not res["terminated"].any() and (res["steps"] == 40).all()


def test_delay_shows_each_member_its_own_past():
    rec = Recorder()
    run(venv(3), rec, [0, 1, 2], Perturbation(delay=np.array([0, 2, 5])))
    plain = Recorder()
    run(venv(3), plain, [0, 1, 2], Perturbation())
    for k in range(40):
        for i, d in enumerate((0, 2, 5)):
            np.testing.assert_array_equal(rec.seen[k][i], plain.seen[max(k - d, 0)][i])


def test_response_one_is_ideal_and_a_lag_slows_the_torque():
    q1, _ = plain_final(2)
    res = run(venv(2), Recorder(), [0, 1], Perturbation(response=np.array([1.0, 1.0])))
    np.testing.assert_array_equal(res["q"], q1)
    lagged = venv(2, steps=3)
    rec_u = []
    real_step = lagged.unwrapped.step

    def spy(a):
        rec_u.append(np.array(a))
        return real_step(a)

    lagged.unwrapped.step = spy
    run(lagged, Recorder(1.0), [0, 1], Perturbation(response=np.array([0.5, 1.0])))
    # u_k = u_{k-1} + r (1 - u_{k-1}) from 0: 0.5, 0.75, 0.875 for r = 0.5; 1, 1, 1 for r = 1 (normalized)
    np.testing.assert_allclose(np.array(rec_u)[:, :, 0], [[0.5, 1.0], [0.75, 1.0], [0.875, 1.0]], rtol=1e-6)


def test_noise_reaches_only_the_named_entries_and_torque_noise_moves_the_plant():
    rec = Recorder()
    run(venv(2), rec, [0, 1], Perturbation(noise_sigma=np.array([0.0, 0.3]), noise_index=(4, 5)))
    plain = Recorder()
    run(venv(2), plain, [0, 1], Perturbation())
    seen, clean = np.array(rec.seen), np.array(plain.seen)
    np.testing.assert_array_equal(seen[:, 0], clean[:, 0])  # sigma 0: untouched
    np.testing.assert_array_equal(seen[:1, 1, :4], clean[:1, 1, :4])  # the angles' entries untouched at the start
    assert 0.2 < np.std(seen[:1, 1, 4:] - clean[:1, 1, 4:]) or np.abs(seen[0, 1, 4:] - clean[0, 1, 4:]).max() > 0.01
    a = run(venv(2), Recorder(), [0, 1], Perturbation(torque_sigma=np.array([0.0, 2.0])))
    q, _ = plain_final(2)
    np.testing.assert_array_equal(a["q"][0], q[0])
    assert np.abs(a["q"][1] - q[1]).max() > 1e-6


def test_pulses_enter_as_impulses():
    """A pulse on the passive joint changes the motion; its momentum effect over one step is tau dt (apply_impulse)."""
    steps = 40
    pulses = np.zeros((2, steps, 2))
    pulses[1, 10:20, 0] = 3.0
    res = run(venv(2, steps), Recorder(0.0), [0, 0], Perturbation(pulses=pulses))
    assert np.array_equal(res["q"][0], plain_final(1, 0.0)[0][0])
    assert np.abs(res["q"][1] - res["q"][0]).max() > 1e-3


def test_gaussian_pulses_shape_and_peak():
    t = np.arange(0, 3, 0.01)
    g = gaussian_pulses(t, np.array([[[1.0], [2.0]]]), np.array([[[0.1], [0.05]]]), np.array([[[2.0], [-1.0]]]))
    assert g.shape == (1, len(t), 2)
    assert g[0, 100, 0] == pytest.approx(2.0) and g[0, 200, 1] == pytest.approx(-1.0)


def test_random_pulses_follow_their_generator():
    t = np.arange(5000) * 0.002
    rng = np.random.default_rng(0)
    P = dfki.random_pulses(rng, 50, t)
    assert P.shape == (50, 5000, 2)
    # three pulses per joint: peaks between 0.5 and 5 N m in magnitude
    for e in range(5):
        for j in range(2):
            peak = np.abs(P[e, :, j]).max()
            assert 0.45 <= peak <= 5.0 + 1e-9


def test_final_success_rule():
    q = np.array([[np.pi / 2 + 0.3, -0.3], [np.pi / 2 + 0.36, 0.0], [np.pi / 2 + 2 * np.pi, 0.0], [np.pi / 2, 0.0]])
    v = np.array([[0.9, -0.9], [0.0, 0.0], [0.0, 0.0], [0.0, 1.1]])
    np.testing.assert_array_equal(dfki.final_success(q, v), [True, False, True, False])


def test_model_variations_follow_their_axes():
    pts = dfki.model_variations()
    assert len(pts) == 5 * 21 + 2 * 11
    names = [n for n, _, _ in pts]
    assert names.count("m2r2") == 21 and names.count("b1") == 11
    skipped = [(n, v) for n, v, p in pts if p is None]
    assert len(skipped) == 11  # m1r1 x1.25; m2r2 above x1.11; m2 x1.25; I2 below x0.81: no rigid link
    nominal = presets.planar2r_params(presets.DFKI_C1)
    mid = [p for n, v, p in pts if n == "I1"][10]
    assert mid == pytest.approx(nominal)
    m2r2_low = [p for n, v, p in pts if n == "m2r2"][0]
    assert m2r2_low["r2"] == pytest.approx(0.75 * presets.DFKI_C1.r2)
    # I2 about the joint is held: the centre-of-mass inertia grows as r2 shrinks
    assert m2r2_low["I2"] == pytest.approx(presets.DFKI_C1.I2 - presets.DFKI_C1.m2 * (0.75 * presets.DFKI_C1.r2) ** 2)


def test_sweep_runs_every_axis_batched(monkeypatch, capsys):
    """A small sweep (3 values, 4 pulse episodes) of a do-nothing policy on the acrobot protocol: it never
    swings up, so every axis fails; the structure and the score's arithmetic are checked; with ``progress`` a bar
    counts the axes (a sweep run on its own, minutes long, printed nothing)."""
    monkeypatch.setattr(dfki, "PULSES", {**dfki.PULSES, "episodes": 4})

    class Nothing:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros((len(obs), 1), np.float32), state

    monkeypatch.setattr(gym.envs.registration.registry["mbs_envs/AcrobotDFKI-v1"], "max_episode_steps", 50)
    monkeypatch.setattr(
        dfki, "random_pulses", lambda rng, episodes, t: np.zeros((episodes, len(t), 2))
    )  # 0.1 s: no room for 6 pulses
    res = dfki.sweep("mbs_envs/AcrobotDFKI-v1", lambda env: Nothing(), n=3, progress=True)
    assert f"{len(dfki.AXES)}/{len(dfki.AXES)}" in capsys.readouterr().err
    assert set(res) == set(dfki.AXES) | {"score"}
    assert len(res["model"]["values"]) + len(res["model"]["skipped"]) == 5 * 3 + 2 * 2
    assert len(res["perturbations"]["success"]) == 4
    assert all(res[a]["fraction"] == 0.0 for a in dfki.AXES) and res["score"]["value"] == 0.0


def test_a_part_of_a_batch_sees_what_it_sees_in_the_whole_batch():
    """``run(batch=(total, first))``: members run in parts (each its rows of the batch's noise) end bit for bit where they
    end in the whole batch, under every axis at once (a controller with memory: the adaptive swing-up's filter and
    identification, noisy velocities, torque noise, a lag, delays, pulses and its own plant per member); a part that
    does not fit in the batch is refused."""
    from mbs_envs.controllers import AdaptiveSwingUpLQR

    env_id, n, steps = "mbs_envs/AcrobotDFKI-v1", 5, 120
    rng = np.random.default_rng(3)
    p = Perturbation(noise_sigma=np.linspace(0.0, 0.4, n), noise_index=(4, 5), torque_sigma=np.linspace(0.0, 0.5, n),
                     response=np.linspace(0.5, 1.0, n), delay=np.arange(n), pulses=rng.normal(0.0, 0.5, (n, steps, 2)))  # fmt: skip
    params = [dict(m1=presets.DFKI_C1.m1 * s) for s in np.linspace(0.9, 1.1, n)]

    def go(members):
        v = gym.make_vec(env_id, num_envs=members.stop - members.start, vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                         max_episode_steps=steps, member_params=params[members])  # fmt: skip
        res = run(v, AdaptiveSwingUpLQR(gym.make(env_id)), list(range(members.start, members.stop)), p.rows(members), noise_seed=11,
                  batch=(n, members.start))  # fmt: skip
        return np.concatenate([res["q"], res["v"]], axis=1)

    whole = go(slice(0, n))
    parts = np.concatenate([go(slice(0, 2)), go(slice(2, 3)), go(slice(3, n))])
    assert np.all(np.isfinite(whole)) and len(np.unique(whole[:, 0])) == n  # the members differ
    np.testing.assert_array_equal(parts, whole)
    with pytest.raises(ValueError, match="batch"):
        run(venv(2), Recorder(), [0, 1], Perturbation(), batch=(3, 2))


def test_a_sweep_in_parts_is_the_whole_sweep(monkeypatch):
    """:func:`dfki.sweep` with parts of 2 members gives each member the value it gets in one batch per axis (the success
    rule replaced by each member's final shoulder angle, so every bit shows), and the parts assemble in any order."""
    monkeypatch.setattr(dfki, "PULSES", {**dfki.PULSES, "episodes": 3})
    monkeypatch.setattr(gym.envs.registration.registry["mbs_envs/AcrobotDFKI-v1"], "max_episode_steps", 60)
    monkeypatch.setattr(dfki, "random_pulses", lambda rng, episodes, t: rng.normal(0.0, 1.0, (episodes, len(t), 2)))
    monkeypatch.setattr(dfki, "run_success", lambda res: res["q"][:, 0].copy())
    from mbs_envs.controllers import SwingUpLQR

    make = lambda env: SwingUpLQR(env)  # noqa: E731
    whole = dfki.sweep("mbs_envs/AcrobotDFKI-v1", make, n=3)
    parted = dfki.sweep("mbs_envs/AcrobotDFKI-v1", make, n=3, part_size=2)
    for axis in dfki.AXES:
        np.testing.assert_array_equal(parted[axis]["success"], whole[axis]["success"])
        assert parted[axis]["values"] == whole[axis]["values"]
    assert parted["score"] == whole["score"]
    parts, meta = dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=3, part_size=2)
    assert max(p.members.stop - p.members.start for p in parts) == 2 and len(parts) > len(dfki.AXES)
    ok = [np.full(p.members.stop - p.members.start, float(p.members.start)) for p in parts]
    order = np.random.default_rng(0).permutation(len(parts))
    a = dfki.assemble_sweep(meta, parts, ok)
    b = dfki.assemble_sweep(meta, [parts[i] for i in order], [ok[i] for i in order])
    for axis in dfki.AXES:
        np.testing.assert_array_equal(a[axis]["success"], b[axis]["success"])
    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="part_size"):
            dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=3, part_size=bad)
    with pytest.raises(ValueError, match="make up its batch"):  # a part missing, or given twice
        dfki.assemble_sweep(meta, parts[1:], ok[1:])
    with pytest.raises(ValueError, match="make up its batch"):
        dfki.assemble_sweep(meta, parts + parts[:1], ok + ok[:1])


def test_a_tuning_set_draws_the_axes_values_apart_from_the_grid():
    """``draw_seed``: every axis' values drawn over its range (reproducibly, another seed other values), none on the grid;
    the noise seeds and pulses those of the sweep's ``seed`` as ever."""
    grid, meta_grid = dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=5, seed=1)
    drawn, meta = dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=5, seed=1, draw_seed=7)
    again, meta_again = dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=5, seed=1, draw_seed=7)
    _, meta_other = dfki.sweep_parts("mbs_envs/AcrobotDFKI-v1", n=5, seed=1, draw_seed=8)
    assert meta_again == meta and meta_other != meta
    for axis, (low, high) in dfki.RANGES.items():
        v, g = np.array(meta[axis]["values"]), np.array(meta_grid[axis]["values"])
        assert len(v) == 5 and ((v >= low) & (v <= high)).all() and not np.isin(v, g).any(), axis
    drawn_model = meta["model"]["values"] + meta["model"]["skipped"]
    nominal = {"m1r1": presets.DFKI_C1.m1 * presets.DFKI_C1.r1, "m2r2": presets.DFKI_C1.m2 * presets.DFKI_C1.r2}
    for name in dfki.MODEL_FACTORS:
        f = np.array([v for n, v in drawn_model if n == name]) / nominal.get(
            name, getattr(presets.DFKI_C1, name, None) or 1.0
        )
        assert (
            len(f) == 5
            and ((f >= 0.75) & (f <= 1.25)).all()
            and not np.isin(np.round(f, 12), np.round(np.linspace(0.75, 1.25, 5), 12)).any()
        ), name
    for name in dfki.MODEL_DAMPING:
        b = np.array([v for n, v in drawn_model if n == name])
        assert len(b) == 3 and ((b >= 0.0) & (b <= 0.1)).all() and not np.isin(b, np.linspace(0.0, 0.1, 3)).any(), name
    for a, b in zip(grid, drawn):  # one part per axis: the same noise seed and pulses
        assert a.axis == b.axis and a.noise_seed == b.noise_seed
        if a.axis == "perturbations":
            np.testing.assert_array_equal(a.perturbation.pulses, b.perturbation.pulses)
