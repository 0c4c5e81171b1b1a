#!/usr/bin/env python
"""Acrobot-v0's model against Gymnasium's Acrobot-v1: the same physics, and each one's integration error.

1. Accelerations: ``Planar2R(driven=(1,))`` with Acrobot-v1's parameters (g = 9.8, unit masses
   and lengths, centres at half length, unit inertia about each centre; ``th1 = theta1 - pi/2``)
   against ``AcrobotEnv._dsdt`` (its ``book`` equations) on random states and elbow torques.
2. Integration error over the same motion: the elbow torque drawn from Acrobot-v1's {-1, 0, 1}
   and held per 0.2 s for 20 s from a start; Acrobot-v1 steps it as it does (one RK4 step of
   0.2 s per action, its velocity clipping), ours as Acrobot-v0 does (RK4, two 5 ms steps per
   10 ms control step); both against a reference (DOP853, rtol 1e-12, restarted at every
   torque change) at every 0.2 s.

Writes ``acrobot_equivalence.json`` and ``.png`` to ``--out``.

    python scripts/acrobot_equivalence.py --out results/acrobot
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np
from gymnasium.envs.classic_control.acrobot import AcrobotEnv
from scipy.integrate import solve_ivp
from tqdm import tqdm

from mbs_envs.dynamics import integrators
from mbs_envs.dynamics.simulate import advance
from mbs_envs.models import Planar2R
from mbs_envs.studies.plotting import pyplot, save

#: Acrobot-v1's physical constants in Planar2R's names
ACROBOT_PARAMS = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "r1": 0.5, "r2": 0.5, "I1": 1.0, "I2": 1.0, "g": 9.8}
STARTS = {"from hanging": [0.1, -0.1, 0.0, 0.0], "from horizontal": [np.pi / 2, 0.3, 0.0, 0.0]}


def to_ours(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Acrobot-v1's state ``(theta1, theta2, dtheta1, dtheta2)`` as ``(q, v)`` of Planar2R."""
    s = np.asarray(s, float)
    return np.stack([s[..., 0] - np.pi / 2, s[..., 1]], axis=-1), s[..., 2:4]


def angle_error(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Max-norm of the wrapped angle difference, shape ``(...)``."""
    return np.max(np.abs((qa - qb + np.pi) % (2 * np.pi) - np.pi), axis=-1)


def accelerations(n: int = 10_000, seed: int = 0) -> dict:
    env, model = AcrobotEnv(), Planar2R(**ACROBOT_PARAMS, driven=(1,))
    rng = np.random.default_rng(seed)
    s = np.column_stack(
        [
            rng.uniform(-np.pi, np.pi, (n, 2)),
            rng.uniform(-4 * np.pi, 4 * np.pi, n),
            rng.uniform(-9 * np.pi, 9 * np.pi, n),
        ]
    )
    a = rng.uniform(-1, 1, n)
    q, v = to_ours(s)
    ours = model.forward_dynamics(q, v, a[:, None])
    theirs = np.array(
        [env._dsdt(np.r_[s[k], a[k]])[2:4] for k in tqdm(range(n), desc="Acrobot-v1 accelerations", mininterval=1)]
    )
    rel = np.max(np.abs(ours - theirs), axis=-1) / np.max(np.abs(theirs), axis=-1)
    return {
        "states": n,
        "max_relative_difference": float(rel.max()),
        "median_relative_difference": float(np.median(rel)),
        "relative": rel,
    }


def motions(t_final: float = 20.0, seed: int = 1) -> dict:
    env, model = AcrobotEnv(), Planar2R(**ACROBOT_PARAMS, driven=(1,))
    rk4 = integrators.get("rk4")
    rng = np.random.default_rng(seed)
    n = int(round(t_final / env.dt))
    out = {}
    for name, s0 in STARTS.items():
        actions = rng.integers(0, 3, n)
        env.reset(seed=0)
        env.state = np.array(s0, float)
        q, v = to_ours(s0)
        q_ref, v_ref = q.copy(), v.copy()
        err_v1, err_ours = [], []
        for k in tqdm(range(n), desc=name, mininterval=1):
            torque = float(env.AVAIL_TORQUE[actions[k]])
            env.step(actions[k])
            for _ in range(20):  # Acrobot-v0: 10 ms control steps of two 5 ms RK4 steps
                q, v = advance(model, rk4, 0.0, q, v, 0.01, 2, np.array([torque]))

            def f(t, x, torque=torque):
                return np.r_[x[2:], model.forward_dynamics(x[:2], x[2:], [torque])]

            sol = solve_ivp(f, (0.0, env.dt), np.r_[q_ref, v_ref], method="DOP853", rtol=1e-12, atol=1e-12)
            q_ref, v_ref = sol.y[:2, -1], sol.y[2:, -1]
            q1, _ = to_ours(env.state)
            err_v1.append(float(angle_error(q1, q_ref)))
            err_ours.append(float(angle_error(q, q_ref)))
        out[name] = {"t": (np.arange(1, n + 1) * env.dt).tolist(), "acrobot_v1": err_v1, "acrobot_v0": err_ours}
    return out


def run(out: pathlib.Path, n: int = 10_000, t_final: float = 20.0) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    acc = accelerations(n)
    mot = motions(t_final)
    plt = pyplot()
    fig, axes = plt.subplots(1, 1 + len(mot), figsize=(5 * (1 + len(mot)), 3.8))
    axes[0].hist(np.log10(np.maximum(acc["relative"], 1e-18)), bins=40)
    axes[0].set_xlabel("log10 relative difference of accelerations (-18: identical)")
    axes[0].set_ylabel("states")
    axes[0].set_title(f"{n} random states: max {acc['max_relative_difference']:.1e}", fontsize=9)
    for ax, (name, m) in zip(axes[1:], mot.items()):
        ax.semilogy(m["t"], np.maximum(m["acrobot_v1"], 1e-16), label="Acrobot-v1 (RK4, one 0.2 s step)")
        ax.semilogy(m["t"], np.maximum(m["acrobot_v0"], 1e-16), label="Acrobot-v0 (RK4, 5 ms steps)")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("angle error against DOP853 1e-12 [rad]")
        ax.set_title(f"same torques, {name}", fontsize=9)
        ax.legend(fontsize=7)
    save(fig, out / "acrobot_equivalence.png")
    summary = {"accelerations": {k: v for k, v in acc.items() if k != "relative"},
               "motions": {name: {"final_error_acrobot_v1": m["acrobot_v1"][-1], "final_error_acrobot_v0": m["acrobot_v0"][-1],
                                  "max_error_acrobot_v1": max(m["acrobot_v1"]), "max_error_acrobot_v0": max(m["acrobot_v0"]),
                                  "error_at_1s_acrobot_v1": m["acrobot_v1"][4], "error_at_1s_acrobot_v0": m["acrobot_v0"][4]}
                           for name, m in mot.items()}}  # fmt: skip
    (out / "acrobot_equivalence.json").write_text(json.dumps({**summary, "traces": mot}, indent=1))
    print(json.dumps(summary, indent=1))
    return summary


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--states", type=int, default=10_000)
    p.add_argument("--t-final", type=float, default=20.0)
    args = p.parse_args(argv)
    run(args.out, args.states, args.t_final)
    return 0


if __name__ == "__main__":
    sys.exit(main())
