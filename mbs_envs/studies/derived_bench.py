"""The derived scenes timed against their hand-written twins, and their first make in fresh processes (the logic of ``scripts/bench_derived.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import numpy as np
from tqdm import tqdm


ROOT = pathlib.Path(__file__).resolve().parents[2]


#: the user's code: the 2R arm from its Lagrangian, registered (Planar2R-v0's defaults)
USER_CODE = """
import numpy as np, sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from mbs_envs.models import symbolic
from mbs_envs.envs import derived
from mbs_envs.envs.planar2r import Planar2REnv

t = dynamicsymbols._t
q1, q2 = dynamicsymbols("q1 q2")
m1, m2, l1, l2, r1, r2, I1, I2, g = sp.symbols("m1 m2 l1 l2 r1 r2 I1 I2 g")
x1, y1 = r1 * sp.cos(q1), r1 * sp.sin(q1)
x2, y2 = l1 * sp.cos(q1) + r2 * sp.cos(q1 + q2), l1 * sp.sin(q1) + r2 * sp.sin(q1 + q2)
d = lambda e: e.diff(t)
T = (m1 * (d(x1)**2 + d(y1)**2) + I1 * d(q1)**2 + m2 * (d(x2)**2 + d(y2)**2) + I2 * (d(q1) + d(q2))**2) / 2
V = g * (m1 * y1 + m2 * y2)
params = dict(m1=1.0, m2=1.0, l1=1.0, l2=1.0, r1=0.5, r2=0.5, I1=1 / 12, I2=1 / 12, g=9.81, b1=0.0, b2=0.0)
model = symbolic.derive("Arm2R", [q1, q2], T, V, params, damping={q1: "b1", q2: "b2"})
centre = (Planar2REnv.center_low + Planar2REnv.center_high) / 2
derived.register("bench/Arm2R-v0", model, torque_limit=(40.0, 20.0), posture=centre, substeps=2,
                 spread=(Planar2REnv.center_high - Planar2REnv.center_low) / 2, amplitude=Planar2REnv.max_amplitude,
                 coordinates=(q1, q2), points=[(0, 0), (l1 * sp.cos(q1), l1 * sp.sin(q1)), (x2 + (l2 - r2) * sp.cos(q1 + q2), y2 + (l2 - r2) * sp.sin(q1 + q2))])
"""


#: the four-bar from its Lagrangian and loop closure, registered with FourBar-v0's settings
FOURBAR_CODE = """
import numpy as np, sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from mbs_envs.models import symbolic, FourBar
from mbs_envs.envs import derived

t = dynamicsymbols._t
th1, ph2, ph1 = dynamicsymbols("th1 ph2 ph1")
l0, l1, l2, l3, m1, m2, m3, r1, r2, r3, I1, I2, I3, g = sp.symbols("l0 l1 l2 l3 m1 m2 m3 r1 r2 r3 I1 I2 I3 g")
x1, y1 = r1 * sp.cos(th1), r1 * sp.sin(th1)
x2, y2 = l1 * sp.cos(th1) + r2 * sp.cos(th1 + ph2), l1 * sp.sin(th1) + r2 * sp.sin(th1 + ph2)
d = lambda e: e.diff(t)
T = (m1 * (d(x1)**2 + d(y1)**2) + I1 * d(th1)**2 + m2 * (d(x2)**2 + d(y2)**2) + I2 * (d(th1) + d(ph2))**2 + (I3 + m3 * r3**2) * d(ph1)**2) / 2
V = g * (m1 * y1 + m2 * y2 + m3 * r3 * sp.sin(ph1))
phi = [l1 * sp.cos(th1) + l2 * sp.cos(th1 + ph2) - l0 - l3 * sp.cos(ph1), l1 * sp.sin(th1) + l2 * sp.sin(th1 + ph2) - l3 * sp.sin(ph1)]
hand = FourBar()
params = {k: getattr(hand.params, k) for k in "l0 l1 l2 l3 m1 m2 m3 r1 r2 r3 I1 I2 I3 g b1 b2 b3".split()}
model = symbolic.derive("FourBarD", [th1, ph2, ph1], T, V, params, [[1.0], [0.0], [0.0]], {th1: "b1", ph2: "b2", ph1: "b3"},
                        constraints=phi, independent=[th1])
derived.register("bench/FourBarD-v0", model, torque_limit=8.0, posture=[0.0], spread=np.pi, amplitude=0.5, rate=(1.0, 4.0),
                 guess=hand.assemble(0.0))
"""


#: the 2R arm with only the elbow driven, registered with the swing-up task and Acrobot-v1's settings
ACROBOT_CODE = (
    USER_CODE.split("model = symbolic.derive")[0]
    + """
model = symbolic.derive("Acrobot2R", [q1, q2], T, V, params, actuation=[[0.0], [1.0]])
derived.register("bench/Acrobot2R-v0", model, task="swing-up", max_episode_steps=1500, torque_limit=10.0, substeps=2,
                 upright=(np.pi / 2, 0.0), hanging=(-np.pi / 2, 0.0))
"""
)


#: mechanism -> (user code, derived id, hand-written id)
PAIRS = {"2R arm": (USER_CODE, "bench/Arm2R-v0", "mbs_envs/Planar2R-v0"),
         "four-bar": (FOURBAR_CODE, "bench/FourBarD-v0", "mbs_envs/FourBar-v0"),
         "acrobot (swing-up task)": (ACROBOT_CODE, "bench/Acrobot2R-v0", "mbs_envs/Acrobot-v1")}  # fmt: skip


FIRST = """
import time
t0 = time.perf_counter()
import gymnasium as gym
import mbs_envs
{user}
env = gym.make("{env_id}")
env.reset(seed=0)
env.step(env.action_space.sample())
t1 = time.perf_counter() - t0
from mbs_envs.dynamics import background  # the child compiling meanwhile writes into the cache folder: let it finish
background.wait()
print(t1)
"""


#: the scenes whose first make is timed: label -> (user code to run first, id)
FIRST_MAKES = {"2R arm (user code)": (USER_CODE, "bench/Arm2R-v0"), "SliderCrank-v0": ("", "mbs_envs/SliderCrank-v0"),
               "CartDoublePendulum-v0": ("", "mbs_envs/CartDoublePendulum-v0"), "CartPoleSwingUp-v0": ("", "mbs_envs/CartPoleSwingUp-v0")}  # fmt: skip


def first_make(user: str, env_id: str) -> dict:
    """Fresh-process seconds to the first step of a derived scene: caches empty, then warm (twice, the least)."""
    out = {}
    with tempfile.TemporaryDirectory() as derived_cache, tempfile.TemporaryDirectory() as numba_cache:
        env = {**os.environ, "MBS_ENVS_DERIVED_CACHE": derived_cache, "NUMBA_CACHE_DIR": numba_cache}
        code = FIRST.format(user=user, env_id=env_id)
        for label in ("cold", "warm", "warm again"):
            res = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=ROOT
            )
            out[label] = float(res.stdout.strip().splitlines()[-1])
    return {"cold_s": out["cold"], "warm_s": min(out["warm"], out["warm again"])}


def steps(pair: str, repeats: int, n_steps: int, num_envs: int) -> dict:
    import gymnasium as gym

    import mbs_envs  # noqa: F401
    from mbs_envs.studies.benchmarking import time_steps

    user, derived_id, hand_id = PAIRS[pair]
    exec(user, {})
    rng = np.random.default_rng(0)
    ids = {"derived": derived_id, "hand-written": hand_id}
    singles = {k: gym.make(v) for k, v in ids.items()}
    vectors = {
        k: gym.make_vec(v, num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False)
        for k, v in ids.items()
    }
    nu = singles["derived"].action_space.shape[0]
    a1 = list(rng.uniform(-1, 1, (n_steps, nu)).astype(np.float32))
    aB = list(rng.uniform(-1, 1, (max(n_steps // 10, 20), num_envs, nu)))
    single = {k: [] for k in ids}
    batched = {k: [] for k in ids}
    for _ in tqdm(range(repeats), desc=f"{pair}: interleaved repeats"):
        for k in ids:  # interleaved: both see the same machine state
            single[k].append(time_steps(singles[k], a1, 400))
            batched[k].append(time_steps(vectors[k], aB, 10**9) / num_envs)
    med = lambda xs: float(np.median(xs))  # noqa: E731
    return {"single_us": {k: med(v) * 1e6 for k, v in single.items()}, "batched_us": {k: med(v) * 1e6 for k, v in batched.items()},
            "single_ratio": med(single["derived"]) / med(single["hand-written"]),
            "batched_ratio": med(batched["derived"]) / med(batched["hand-written"])}  # fmt: skip
