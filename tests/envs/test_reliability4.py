"""Reliability, fourth round: threads on a cold cache, the fallback that must flag, set_attr's rule, a damaged
cache file, spec serialization, script arguments, controller refusals, simulate's state arrays."""

import os
import pathlib
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs
from mbs_envs.envs import registry

ROOT = pathlib.Path(__file__).resolve().parents[2]
IDS = [i for i in gym.registry if i.startswith("mbs_envs/")]


def run_python(code: str, tmp_path: pathlib.Path, **env: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter with empty numba and derivation caches (a first use after an install)."""
    full = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "MBS_ENVS_DERIVED_CACHE": str(tmp_path / "derived"),
            **env}  # fmt: skip
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=tmp_path, env=full, capture_output=True,
                          text=True, timeout=600)  # fmt: skip


# -- 1. threads on a cold cache ---------------------------------------------------------------------------------


def test_derive_from_four_threads_into_an_empty_cache(tmp_path):
    """Each thread derives and loads the same model: the generated module is run by one thread at a time and the
    cache files are written under names of their own (a module half-run, a shared temporary file: 2 of 4 failed)."""
    res = run_python("""
        import concurrent.futures as cf
        import numpy as np, sympy as sp
        from mbs_envs.models import symbolic
        from mbs_envs.models.symbolic import dynamicsymbols

        def job(k):
            t = symbolic.time_symbol()
            q1, q2 = dynamicsymbols("q1 q2")
            m, l, g = sp.symbols("m l g")
            T = m * l**2 * (q1.diff(t) ** 2 + (q1.diff(t) + q2.diff(t)) ** 2) / 2
            V = -m * g * l * (sp.cos(q1) + sp.cos(q1 + q2))
            M = symbolic.derive("Arm", [q1, q2], T, V, {"m": (1.0, "positive"), "l": (1.0, "positive"), "g": 9.81})
            return np.asarray(M.mass_matrix(np.array([0.1, 0.2]))).tolist()

        with cf.ThreadPoolExecutor(4) as ex:
            results = [f.result() for f in [ex.submit(job, k) for k in range(4)]]
        assert all(r == results[0] for r in results)
        print("ok")
    """, tmp_path)  # fmt: skip
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-2000:]


def test_envs_built_in_threads_on_a_cold_kernel_cache():
    """One env per thread, twelve threads, three scenes whose kernels are not compiled yet (the default background
    mode runs their Python meanwhile): every job makes, resets and steps (the soak's part, one fresh interpreter)."""
    from mbs_envs.studies.reliability import threads_cold

    ids = ["mbs_envs/SpatialChain-v0", "mbs_envs/CartPoleSwingUp-v0", "mbs_envs/FourBar-v0"]
    result = threads_cold(ids, per_id=4, runs=1)
    assert result["jobs"] == 12 and result["failed"] == 0, result["errors"]


# -- 2. the fallback flags divergence as the compiled code does --------------------------------------------------


@pytest.mark.parametrize("mode", ["python", "sync"])
def test_a_runaway_step_is_flagged_in_every_execution_mode(tmp_path, mode):
    res = run_python("""
        import numpy as np, gymnasium as gym, mbs_envs
        env = gym.make("mbs_envs/CartPoleSwingUp-v0", torque_limit=1e200, integrator="rk4")
        env.reset(seed=0)
        obs, reward, terminated, truncated, info = env.step(np.ones(1, np.float32))
        assert info["diverged"] and terminated and np.all(np.isfinite(obs)), info
        print("flagged")
    """, tmp_path, MBS_ENVS_JIT=mode)  # fmt: skip
    assert res.returncode == 0 and res.stdout.strip() == "flagged", res.stderr[-2000:]


# -- 4. set_attr: one rule per ecosystem, every adapter ----------------------------------------------------------


def test_vector_set_attr_follows_gymnasiums_rule():
    venv = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="one value per member"):
        venv.set_attr("u_max", [5.0, 2.0])  # 2 values for 3 members: refused whatever their meaning
    assert np.array_equal(venv.get_attr("u_max")[0], [40.0, 20.0])  # refused: nothing changed
    venv.set_attr("u_max", np.array([5.0, 2.0]))  # one value for all
    venv.set_attr("u_max", [np.array([6.0, 3.0])] * 3)  # one per member
    assert np.array_equal(venv.get_attr("u_max")[2], [6.0, 3.0])
    with pytest.raises(ValueError, match="equal"):
        venv.set_attr("start_noise", [0.1, 0.2, 0.3])
    two = gym.make_vec("mbs_envs/Planar2R-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="one value per member"):  # the same list, the same refusal, at 2 members
        two.set_attr("start_noise", [0.1])


def test_sb3_set_attr_takes_one_value_on_every_adapter_perturbed_included():
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    for perturb in (None, "dfki"):
        env = make_sb3_vec_env("mbs_envs/AcrobotDFKI-v1", n_envs=2, seed=0, perturb=perturb)
        env.set_attr("start_noise", 0.05)
        assert env.get_attr("start_noise") == [0.05, 0.05]
        env.set_attr("u_max", [2.0])  # SB3's rule: a list is one value (the torque limits)
        with pytest.raises(ValueError, match="start_nose"):
            env.set_attr("start_nose", 0.1)
        env.close()


# -- 5. a damaged cache file is rebuilt, with a warning ----------------------------------------------------------


@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_a_damaged_derivation_source_is_generated_again(tmp_path, damage):
    make = "import numpy as np, gymnasium as gym, mbs_envs; e = gym.make('mbs_envs/SliderCrank-v0'); e.reset(seed=0); print('ok')"
    first = run_python(make, tmp_path, MBS_ENVS_JIT="python")
    assert first.returncode == 0, first.stderr[-2000:]
    sources = list((tmp_path / "derived").glob("derivation_*.source"))
    assert sources
    for path in sources:
        text = path.read_text()
        path.write_text(text[: len(text) // 2] if damage == "truncate" else "def (:\n\x00garbage")
    again = run_python(make, tmp_path, MBS_ENVS_JIT="python")
    assert again.returncode == 0 and again.stdout.strip() == "ok", again.stderr[-2000:]
    assert "damaged derivation cache file" in again.stderr
    third = run_python(make, tmp_path, MBS_ENVS_JIT="python")  # repaired: no warning any more
    assert third.returncode == 0 and "damaged" not in third.stderr


# -- 7. spec serialization ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", IDS)
def test_every_spec_serializes_and_its_vector_entry_point_still_works(env_id):
    from gymnasium.envs.registration import EnvSpec

    spec = gym.spec(env_id)
    back = EnvSpec.from_json(spec.to_json())
    assert back.id == spec.id and back.vector_entry_point == spec.vector_entry_point
    assert isinstance(spec.vector_entry_point, str)
    kwargs = {"n_links": 3} if "Chain" in env_id else {}
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    assert type(venv.unwrapped).__name__ == "MBSVectorEnv"
    venv.close()


# -- 9. script arguments, refused before any work in argparse's format ------------------------------------------


@pytest.mark.parametrize("script, args, culprit", [
    ("train.py", ["--eval-every", "-1"], "--eval-every"),
    ("train.py", ["--eval-seeds", "0"], "--eval-seeds"),
    ("train.py", ["--env-kwargs", "[1,2]"], "--env-kwargs"),
    ("train.py", ["--env-kwargs", "{bad"], "--env-kwargs"),
    ("train.py", ["--steps", "0"], "--steps"),
    ("train.py", ["--out", "FILE"], "--out"),
    ("record.py", ["--fps", "0"], "--fps"),
    ("record.py", ["--seconds", "-1"], "--seconds"),
    ("record.py", ["--size", "x"], "--size"),
    ("record.py", ["--out", "FILE"], "--out"),
])  # fmt: skip
def test_script_arguments_are_refused_before_any_work(tmp_path, capsys, script, args, culprit):
    import runpy

    afile = tmp_path / "a_file"
    afile.write_text("")
    args = [str(afile) if a == "FILE" else a for a in args]
    base = {"train.py": ["--env", "mbs_envs/Planar2R-v0", "--algo", "ppo", "--steps", "10", "--out", str(tmp_path / "o")],
            "record.py": ["--env", "mbs_envs/Planar2R-v0", "--policy", "pd", "--out", str(tmp_path / "o")]}[script]  # fmt: skip
    parse = runpy.run_path(str(ROOT / "scripts" / script))["parse_args"]
    with pytest.raises(SystemExit) as e:
        parse(base + args)
    assert e.value.code == 2  # argparse's error exit
    assert f"argument {culprit}" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# -- 10. controllers name what they refuse --------------------------------------------------------------------


CONTROLLERS = [
    (s.id, dict(s.kwargs), name, spec) for s in registry.SCENES if s.compared for name, spec in s.controllers.items()
]


@pytest.mark.parametrize("env_id, kwargs, name, spec", CONTROLLERS, ids=[f"{c[0]}-{c[2]}" for c in CONTROLLERS])
def test_controllers_refuse_a_malformed_observation_naming_it(env_id, kwargs, name, spec):
    env = gym.make(env_id, **kwargs)
    ctrl = registry.load(spec)(env)
    obs, _ = env.reset(seed=0)
    for bad in (np.float32(0.5), obs[:-1], np.zeros((2, obs.size + 1), np.float32)):
        with pytest.raises(ValueError, match="observation"):
            ctrl.predict(bad, deterministic=True)
    action, state = ctrl.predict(np.stack([obs, obs]), episode_start=np.ones(2, bool), deterministic=True)
    if state is not None:  # a controller with memory: a wrong-length episode_start and a malformed state are named
        with pytest.raises(ValueError, match="episode_start"):
            ctrl.predict(np.stack([obs, obs]), state=state, episode_start=np.ones(3, bool), deterministic=True)
        with pytest.raises(ValueError, match="state"):
            ctrl.predict(np.stack([obs, obs]), state=np.zeros(3), episode_start=np.zeros(2, bool), deterministic=True)
    env.close()


# -- 11. simulate never hands its own state to the user's input ------------------------------------------------


@pytest.mark.parametrize("integrator", ["rk4", "euler", "semi_implicit_euler", "rk45", "radau", "implicit_euler"])
def test_a_user_input_cannot_write_into_the_integrators_state(integrator):
    from mbs_envs import simulate
    from mbs_envs.models import Planar2R

    model = Planar2R()

    def writes(t, q, v):
        q[..., 0] = 0.0
        return model.gravity(q)

    with pytest.raises(ValueError, match="read-only"):
        simulate(model, [-1.0, 0.5], [0.0, 0.0], 0.05, dt=1e-2, integrator=integrator, u=writes)
    reads = simulate(
        model, [-1.0, 0.5], [0.0, 0.0], 0.05, dt=1e-2, integrator=integrator, u=lambda t, q, v: model.gravity(q)
    )
    held = simulate(
        model, [-1.0, 0.5], [0.0, 0.0], 0.05, dt=1e-2, integrator=integrator, u=lambda t, q, v: model.gravity(q.copy())
    )
    assert np.array_equal(reads.q, held.q)


def test_mbs_envs_is_imported():
    assert mbs_envs.__version__ == "0.2.0"


# -- 3. a controller acts for the settings it was built with ---------------------------------------------------


@pytest.mark.parametrize("env_id, kwargs, name, spec", CONTROLLERS, ids=[f"{c[0]}-{c[2]}" for c in CONTROLLERS])
@pytest.mark.parametrize("setting", ["u_max", "dt"])
def test_a_controller_refuses_to_act_on_a_setting_changed_after_it_was_built(env_id, kwargs, name, spec, setting):
    env = gym.make(env_id, **kwargs)
    ctrl = registry.load(spec)(env)
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    old = np.array(getattr(base, setting), float)
    setattr(base, setting, old / 4)
    with pytest.raises(ValueError, match=f"built for the env's {setting}"):
        ctrl.predict(obs, deterministic=True)
    setattr(base, setting, old)  # changed back: it acts again, as it did
    action, _ = ctrl.predict(obs, deterministic=True)
    fresh = registry.load(spec)(env)
    assert np.array_equal(action, fresh.predict(obs, deterministic=True)[0])
    env.close()


def test_the_stale_pd_reproduction_is_refused_and_a_controller_built_after_applies_the_new_scale():
    from mbs_envs.controllers import PD

    env = gym.make("mbs_envs/Planar2R-v0")
    obs, _ = env.reset(seed=0)
    before = PD(env)
    env.unwrapped.u_max = env.unwrapped.u_max / 4
    with pytest.raises(ValueError, match="u_max"):
        before.predict(obs)
    after = PD(env)
    action, _ = after.predict(obs)
    _, _, _, _, info = env.step(action)
    assert np.allclose(info["u"], np.clip(action, -1, 1) * env.unwrapped.u_max)


def test_rates_from_angles_refuses_a_changed_step():
    from mbs_envs.controllers import RatesFromAngles, SwingUpLQR

    env = gym.make("mbs_envs/Acrobot-v1")
    obs, _ = env.reset(seed=0)
    wrapped = RatesFromAngles(SwingUpLQR(env), env)
    env.unwrapped.dt = 0.02
    with pytest.raises(ValueError, match="dt"):
        wrapped.predict(obs)


# -- 6. memory has a budget -------------------------------------------------------------------------------------


def test_a_batch_that_cannot_fit_is_refused_at_make_stating_need_and_budget(monkeypatch):
    from mbs_envs.envs.budget import memory_budget

    monkeypatch.delenv("MBS_ENVS_MEMORY_BUDGET", raising=False)
    assert memory_budget() == 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")  # the default
    monkeypatch.setenv("MBS_ENVS_MEMORY_BUDGET", str(8 * 2**30))
    kwargs = {"n_links": 500, "substeps": 1, "vectorization_mode": "vector_entry_point"}
    with pytest.raises(ValueError, match=r"would need about 36 GiB, above the memory budget of 8 GiB"):
        gym.make_vec("mbs_envs/SerialChain-v0", num_envs=100_000, **kwargs)
    monkeypatch.setenv("MBS_ENVS_MEMORY_BUDGET", "1e8")
    with pytest.raises(ValueError, match="0.0931 GiB"):
        gym.make_vec("mbs_envs/Planar2R-v0", num_envs=100_000, vectorization_mode="vector_entry_point")
    gym.make_vec("mbs_envs/Planar2R-v0", num_envs=1_000, vectorization_mode="vector_entry_point").close()
    for bad in ("-1", "lots", "inf"):
        monkeypatch.setenv("MBS_ENVS_MEMORY_BUDGET", bad)
        with pytest.raises(ValueError, match="MBS_ENVS_MEMORY_BUDGET"):
            gym.make_vec("mbs_envs/Planar2R-v0", num_envs=2, vectorization_mode="vector_entry_point")


def test_the_memory_estimate_bounds_what_a_batch_takes():
    """RSS growth of a batch of 4,000 members through reset and three steps stays under the estimate."""
    code = """
        import gc, os, numpy as np, gymnasium as gym, mbs_envs
        from mbs_envs.envs.budget import memory_per_member

        def rss():
            with open("/proc/self/statm") as f:
                return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

        for env_id, kw in (("mbs_envs/Planar2R-v0", {}), ("mbs_envs/SerialChain-v0", {"n_links": 50})):
            small = gym.make_vec(env_id, num_envs=8, vectorization_mode="vector_entry_point", **kw)
            small.reset(seed=0)
            small.step(np.zeros(small.action_space.shape, np.float32))
            small.close()
            gc.collect()
            before, n = rss(), 4000
            v = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)
            v.reset(seed=0)
            for _ in range(3):
                v.step(np.zeros(v.action_space.shape, np.float32))
            m = v.unwrapped.model
            took = (rss() - before) / n
            bound = memory_per_member(m.nq, m.nv, v.single_observation_space.shape[0])
            assert 0 < took < bound, (env_id, took, bound)
        print("ok")
    """
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=600,
                         env={**os.environ, "MBS_ENVS_JIT": "sync"})  # fmt: skip
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-2000:]
