"""Kernels run as Python while a child process compiles them (mbs_envs.dynamics.background): the same bits as
compiled, the switch to compiled code, the fallback where Python raises, the modes."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import gymnasium as gym
import numba
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.dynamics import background, interpreted
from mbs_envs.dynamics.jit import njit
from mbs_envs.dynamics.trig import fma

EPISODES = """
import hashlib
import numpy as np, gymnasium as gym, mbs_envs


def hashes(steps, ids):
    out = {}
    for env_id in ids:
        kw = {"n_links": 4} if "Chain" in env_id else {}
        env = gym.make(env_id, **kw)
        obs, _ = env.reset(seed=3)
        env.action_space.seed(3)
        h = hashlib.sha1(np.asarray(obs).tobytes())
        for i in range(steps):
            o, r, te, tr, info = env.step(env.action_space.sample())
            h.update(np.asarray(o).tobytes()); h.update(np.float64(r).tobytes())
            for k in sorted(info):
                h.update(np.asarray(info[k]).tobytes())
            if te or tr:
                h.update(np.asarray(env.reset()[0]).tobytes())
        out[env_id] = h.hexdigest()
    return out
"""


def _python_hashes(steps: int, ids: list[str]) -> dict:
    """The episodes on the kernels' Python alone, in a fresh process (``MBS_ENVS_JIT=python``: nothing compiled)."""
    code = EPISODES + "\nimport json, sys\nprint(json.dumps(hashes(int(sys.argv[1]), sys.argv[2:])))\n"
    env = {**os.environ, background.ENV_VAR: "python"}
    res = subprocess.run(
        [sys.executable, "-c", code, str(steps), *ids], env=env, capture_output=True, text=True, timeout=900
    )
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def _compiled_hashes(steps: int, ids: list[str]) -> dict:
    """The same episodes here, compiled (this test run's mode, ``sync``: the kernels the other tests compiled)."""
    assert background.mode() == "sync"
    ns: dict = {}
    exec(EPISODES, ns)
    return ns["hashes"](steps, ids)


@pytest.mark.parametrize(
    "ids",
    [
        pytest.param(
            ["mbs_envs/Planar2R-v0", "mbs_envs/FourBar-v0", "mbs_envs/SpatialChain-v0", "mbs_envs/Acrobot-v1"],
            id="fast",
        ),
        pytest.param(
            sorted(k for k in gym.registry if k.startswith("mbs_envs/")), id="every-id", marks=pytest.mark.slow
        ),
    ],
)
def test_episodes_run_as_python_are_bit_for_bit_the_compiled_ones(ids):
    """Every step of an episode (observations, rewards, every info entry, resets) on the kernels' Python alone
    (``MBS_ENVS_JIT=python``: nothing compiled) against the compiled kernels (``sync``); a closed chain, a spatial
    chain and a SymPy-derived model among them (their friction's ``tanh``, whose numpy version is 1 ulp off libm's
    now and then, and ``x ** 2``, whose libm ``pow`` is 1 ulp off ``x * x`` now and then, made them differ before
    the kernels' Python called libm's and numba's own)."""
    steps = 200 if len(ids) < 6 else 1000
    assert _python_hashes(steps, ids) == _compiled_hashes(steps, ids)


KERNEL = """
import math
import numpy as np
from mbs_envs.dynamics.jit import njit


@njit
def scaled_sum(x, s):
    acc = 0.0
    for i in range(x.shape[0]):
        acc += math.tanh(x[i]) * s + np.exp(-x[i]) ** 2
    return acc
"""


def test_a_new_call_runs_as_python_until_the_child_process_has_compiled_it(monkeypatch, tmp_path):
    """Within an env's calls (``allowed``), a kernel without compiled code runs as Python while a child process
    compiles it into the disk cache; the first call after that loads it, the same bits; outside, it compiles first."""
    import importlib.util

    monkeypatch.setenv(background.ENV_VAR, "background")
    monkeypatch.setenv(
        "NUMBA_CACHE_DIR", str(tmp_path / "cache")
    )  # the child's cache (this process's is set at import)
    path = tmp_path / "bg_kernel_module.py"
    path.write_text(KERNEL)
    spec = importlib.util.spec_from_file_location("bg_kernel_module", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "bg_kernel_module", module)
    spec.loader.exec_module(module)
    kernel = module.scaled_sum
    x = np.random.default_rng(0).normal(size=257)
    with background.allowed():
        first = kernel(x, 0.3)  # no compiled code: its Python, while the child compiles
        assert len(kernel.overloads) == 0 and background.pending() >= 1
        assert background.wait(timeout=300)
        assert kernel(x, 0.3) == first  # now compiled (loaded from the cache the child wrote): the same bits
    assert len(kernel.overloads) == 1
    kernel(np.asarray(x, np.float32), 0.3)  # other types, outside an env's calls: compiled before it runs
    assert len(kernel.overloads) == 2 and background.pending() == 0
    again = importlib.util.module_from_spec(spec)  # a new process's view: the kernel is in the disk cache only
    spec.loader.exec_module(again)
    with background.allowed():
        assert again.scaled_sum(x, 0.3) == first
    assert len(again.scaled_sum.overloads) == 1 and background.pending() == 0  # loaded here, no child asked


def test_python_that_raises_puts_the_arrays_back_and_the_call_runs_compiled(monkeypatch):
    monkeypatch.setenv(background.ENV_VAR, "python")

    @njit(cache=False)
    def halve_then_invert(x, out):
        for i in range(x.shape[0]):
            x[i] *= 0.5
        out[0] = 1.0 / float(x[0])  # Python raises ZeroDivisionError; compiled code gives inf (error_model="numpy")

    x, out = np.array([0.0, 4.0]), np.array([7.0])
    with background.allowed():
        halve_then_invert(x, out)
    np.testing.assert_array_equal(x, [0.0, 2.0])  # halved once: the Python's writes were undone first
    assert out[0] == np.inf
    assert len(halve_then_invert.overloads) == 1


def test_python_mode_compiles_nothing_and_sync_compiles_before_the_call(monkeypatch):
    @njit(cache=False)
    def twice(x):
        return 2.0 * x

    monkeypatch.setenv(background.ENV_VAR, "python")
    with background.allowed():
        assert twice(1.5) == 3.0 and len(twice.overloads) == 0 and background.pending() == 0
    monkeypatch.setenv(background.ENV_VAR, "sync")
    with background.allowed():
        assert twice(1.5) == 3.0 and len(twice.overloads) == 1


@pytest.mark.parametrize("value", ["fast", "1", "Python3"])
def test_a_mode_that_does_not_exist_is_refused_naming_the_variable(monkeypatch, value):
    @njit(cache=False)
    def one(x):
        return x + 1.0

    monkeypatch.setenv(background.ENV_VAR, value)
    with pytest.raises(ValueError, match=background.ENV_VAR), background.allowed():
        one(1.0)
    assert len(one.overloads) == 0 and background.pending() == 0


def test_numba_power_is_numbas_power():
    @numba.njit(error_model="numpy")  # as the package's kernels: 1 / 0 is inf
    def powers(a, n):
        return a**2, a**3, a**-2, a**7, a**n, a**2.0, a**0.5, a**1.7

    rng = np.random.default_rng(1)
    with np.errstate(all="ignore"):
        for a in np.r_[
            rng.normal(0, 10, 2000), rng.lognormal(0, 20, 200), np.inf, -np.inf, np.nan
        ]:  # (numba raises for 0 ** -2)
            for n in (0, 1, 5, -3):
                want = powers(a, n)
                k = 8 if 0.0 < a < np.inf else 6  # libm's pow of a float exponent: for positive finite bases (math.pow
                got = tuple(interpreted.numba_power(a, e) for e in (2, 3, -2, 7, n, 2.0, 0.5, 1.7)[:k])  # raises else)
                assert np.asarray(got).tobytes() == np.asarray(want[:k]).tobytes(), (a, n, got, want)


def test_the_python_fma_is_the_instruction():
    @numba.njit
    def fused(a, b, c):
        return fma(a, b, c)

    rng = np.random.default_rng(2)
    a, b = rng.normal(size=5000) * 10.0 ** rng.integers(-200, 200, 5000), rng.normal(size=5000)
    c = -a * b  # near-cancellations, where a separate product and sum would differ most
    cases = list(zip(a, b, c)) + [
        (0.0, -1.0, -0.0),
        (-0.0, 1.0, -0.0),
        (0.0, 1.0, -0.0),
        (1.0, 1.0, -1.0),
        (np.inf, 0.0, 1.0),
    ]
    for x, y, z in cases:
        assert np.float64(interpreted.fma_exact(x, y, z)).tobytes() == np.float64(fused(x, y, z)).tobytes(), (x, y, z)


def test_a_single_env_switches_to_compiled_code_without_changing_its_episode(monkeypatch):
    """A single env steps on its step kernel's Python until it is compiled, then compiled: the episode is the same
    bit for bit as one compiled throughout. (The kernel here is compiled already, so the Python is forced for the
    first steps, as a cold cache would.)"""

    def episode(forced: int):
        env = gym.make("mbs_envs/SerialChain-v0", n_links=3)
        u = env.unwrapped
        obs, _ = env.reset(seed=5)
        rng = np.random.default_rng(5)
        h = hashlib.sha1(obs.tobytes())
        for i in range(60):
            u.dispatch._direct = (
                None  # looked up again at every step (a real switch: when the child's answers move the generation)
            )
            if i < forced:  # the Python of its step, as while the child process compiles
                monkeypatch.setattr(background, "entry", lambda k, a: (interpreted.interpreted(k), False))
            else:
                monkeypatch.undo()
            o, r, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            h.update(o.tobytes() + np.float64(r).tobytes())
        monkeypatch.undo()
        return h.hexdigest()

    assert episode(25) == episode(0)
