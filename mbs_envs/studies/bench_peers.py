"""The speed benchmark against peers timed in the same process: single and batched steps against Gymnasium's Acrobot and CartPole, the chains against Pinocchio, MuJoCo, PPO through the SB3 adapter (``scripts/bench.py`` is its command line)."""

from __future__ import annotations

import json
import pathlib
import platform
import time


import gymnasium as gym
import numpy as np
from scipy.integrate import solve_ivp
from tqdm import tqdm

import mbs_envs
from .benchmarking import median_time, pinocchio_chain, time_steps
from ..models import SerialChain
from .plotting import pyplot, save


#: Planar2R-v0 at Acrobot-v1's control step (0.2 s) with its default physics step (5 ms): 40 RK4 substeps.


AT_ACROBOT_DT = {"dt": 0.2, "substeps": 40}


def single_step(repeats: int, steps: int) -> dict:
    rng = np.random.default_rng(0)
    peers = {
        "Acrobot-v1": (gym.make("Acrobot-v1"), [int(a) for a in rng.integers(0, 3, steps)]),
        "Planar2R-v0": (gym.make("mbs_envs/Planar2R-v0"), list(rng.uniform(-1, 1, (steps, 2)).astype(np.float32))),
        "Planar2R-v0 (numpy path)": (
            gym.make("mbs_envs/Planar2R-v0", compiled=False),
            list(rng.uniform(-1, 1, (steps, 2)).astype(np.float32)),
        ),
        "Planar2R-v0 at dt 0.2 s": (
            gym.make("mbs_envs/Planar2R-v0", **AT_ACROBOT_DT),
            list(rng.uniform(-1, 1, (steps, 2)).astype(np.float32)),
        ),
    }
    times: dict[str, list[float]] = {k: [] for k in peers}
    for _ in tqdm(range(repeats), desc="single step"):
        for name, (env, actions) in peers.items():  # interleaved: drift hits both alike
            times[name].append(time_steps(env, actions, reset_every=400))
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {
        "median_step_us": {k: v * 1e6 for k, v in med.items()},
        "ratio_planar2r_to_acrobot": med["Planar2R-v0"] / med["Acrobot-v1"],
        "ratio_planar2r_at_acrobot_dt_to_acrobot": med["Planar2R-v0 at dt 0.2 s"] / med["Acrobot-v1"],
        "error": step_errors(),
    }


def step_errors(n_states: int = 50) -> dict:
    """Largest state error over one control step against DOP853 (rtol 1e-12): Acrobot-v1 and
    Planar2R-v0 each at its defaults, and Planar2R-v0 at Acrobot's control step (:data:`AT_ACROBOT_DT`)."""
    from gymnasium.envs.classic_control.acrobot import AcrobotEnv, rk4

    rng = np.random.default_rng(1)
    acro = AcrobotEnv()
    err_acro = 0.0
    for _ in range(n_states):
        s = np.r_[rng.uniform(-np.pi, np.pi, 2), rng.uniform(-4, 4, 2)]
        torque = float(rng.choice(acro.AVAIL_TORQUE))
        aug = np.append(s, torque)
        ns = rk4(acro._dsdt, aug, [0, acro.dt])  # what Acrobot-v1's step integrates
        ref = solve_ivp(lambda t, y: acro._dsdt(y), (0, acro.dt), aug, method="DOP853", rtol=1e-12, atol=1e-12).y[
            :4, -1
        ]
        err_acro = max(err_acro, float(np.max(np.abs(ns[:4] - ref))))
    env = gym.make("mbs_envs/Planar2R-v0").unwrapped  # its defaults: RK4, 2 substeps per 10 ms
    states = rng.bit_generator.state  # the same states and actions for both settings
    err_ours = planar2r_step_error(env, rng, n_states)
    rng.bit_generator.state = states
    err_02 = planar2r_step_error(gym.make("mbs_envs/Planar2R-v0", **AT_ACROBOT_DT).unwrapped, rng, n_states)
    return {
        "acrobot_dt": acro.dt,
        "acrobot_max_state_error_per_step": err_acro,
        "planar2r_dt": env.dt,
        "planar2r_substeps": env.substeps,
        "planar2r_max_state_error_per_step": err_ours,
        "ratio_acrobot_to_planar2r": err_acro / err_ours,
        "planar2r_at_acrobot_dt": {
            **AT_ACROBOT_DT,
            "max_state_error_per_step": err_02,
            "ratio_acrobot_to_planar2r": err_acro / err_02,
        },
    }


def planar2r_step_error(env, rng: np.random.Generator, n_states: int) -> float:
    """Largest state error of one ``env.step`` from random states and actions, against DOP853 (rtol 1e-12)."""
    model, err = env.model, 0.0
    for _ in range(n_states):
        q, v = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-4, 4, 2)
        action = rng.uniform(-1, 1, 2)
        env.reset(options={"q": q, "v": v})
        env.step(action)  # exactly what a user's step integrates
        ref = mbs_envs.simulate(
            model, q, v, env.dt, dt=env.dt, integrator="dop853", u=action * env.u_max, rtol=1e-12, atol=1e-12
        )
        err = max(err, float(np.max(np.abs(env.q - ref.q[-1]))), float(np.max(np.abs(env.v - ref.v[-1]))))
    return err


def batched_step(num_envs: int, repeats: int, steps: int) -> dict:
    from gymnasium.vector import AutoresetMode

    rng = np.random.default_rng(0)
    peers = {
        "CartPole-v1 vector": gym.make_vec("CartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point"),
        "Planar2R-v0 vector": gym.make_vec(
            "mbs_envs/Planar2R-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False,
            autoreset_mode=AutoresetMode.NEXT_STEP,
        ),
        "Planar2R-v0 vector (full info)": gym.make_vec(
            "mbs_envs/Planar2R-v0", num_envs=num_envs, vectorization_mode="vector_entry_point"
        ),
        "Planar2R-v0 vector (numpy path)": gym.make_vec(
            "mbs_envs/Planar2R-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False,
            compiled=False,
        ),
    }  # fmt: skip
    actions = {
        name: [env.action_space.sample() for _ in range(steps)]
        if "CartPole" in name
        else list(rng.uniform(-1, 1, (steps, num_envs, 2)))
        for name, env in peers.items()
    }
    times: dict[str, list[float]] = {k: [] for k in peers}
    for _ in tqdm(range(repeats), desc=f"batched x{num_envs}"):
        for name, env in peers.items():
            times[name].append(time_steps(env, actions[name], reset_every=10**9))
    per_env = {k: float(np.median(v)) / num_envs for k, v in times.items()}
    ref = per_env["CartPole-v1 vector"]
    floor = trig_floor(num_envs, 3)
    return {
        "num_envs": num_envs,
        "trig_floor": {
            **floor,
            **{
                k.replace("per_env_step_us", "ratio_to_cartpole"): v / (ref * 1e6)
                for k, v in floor.items()
                if k.endswith("_us")
            },
        },
        "per_env_step_us": {k: v * 1e6 for k, v in per_env.items()},
        "ratio_to_cartpole": {k: v / ref for k, v in per_env.items()},
    }


def trig_floor(num_envs: int, repeats: int) -> dict:
    """Per member, the time of a default step's sines and cosines alone, by libm and by :func:`mbs_envs.dynamics.trig.sincos`.

    The step needs, per member, the sine and cosine of both joint angles in each
    of 4 RK4 stages of 2 substeps (16 angles), of the 6 reference phases, and of
    the final angles for the observation and the energy (4): 26 angles. By libm
    (numba's ``np.sin``, ``np.cos``: scalar calls) that is 52 calls; the compiled
    step uses the branch-free ``sincos`` instead, which vectorizes.
    """
    import numba

    from mbs_envs.dynamics.trig import sincos

    @numba.njit
    def libm(x, k, out):
        for b in range(x.shape[0]):
            acc = 0.0
            for j in range(k):
                acc += np.sin(x[b] + 0.1 * j) + np.cos(x[b] + 0.1 * j)
            out[b] = acc

    @numba.njit
    def simd(x, k, out):
        for b in range(x.shape[0]):
            out[b] = 0.0
        for j in range(k):
            for b in range(x.shape[0]):
                s, c = sincos(x[b] + 0.1 * j)
                out[b] += s + c

    x = np.random.default_rng(0).uniform(-3, 3, num_envs)
    out = np.empty(num_envs)
    times = {name: float(np.median([median_time(lambda: f(x, 26, out)) for _ in range(repeats)])) / num_envs * 1e6
             for name, f in (("libm", libm), ("simd_sincos", simd))}  # fmt: skip
    return {"angles_per_member": 26, **{f"{k}_per_env_step_us": v for k, v in times.items()}}


def chain_dynamics(batch: int = 256) -> dict:
    rng = np.random.default_rng(0)
    out: dict = {}
    for n in (50, 100, 400):
        chain = SerialChain(n_links=n)
        q, v, u = (rng.uniform(-1, 1, n) for _ in range(3))
        Q, V, U = (rng.uniform(-1, 1, (batch, n)) for _ in range(3))
        row = {
            "aba_single_us": 1e6 * median_time(lambda: chain.aba(q, v, u)),
            "aba_batch_per_env_us": 1e6 * median_time(lambda: chain.aba(Q, V, U)) / batch,
        }
        pin = pinocchio_chain(chain)
        if pin is not None:
            pmod, model, data = pin
            row["pin_aba_single_us"] = 1e6 * median_time(lambda: pmod.aba(model, data, q, v, u))
        out[n] = row
    r = out[100]
    summary = {"rows": out, "batch": batch, "t400_over_t50_batched": out[400]["aba_batch_per_env_us"] / out[50]["aba_batch_per_env_us"],
               "t400_over_t50_single": out[400]["aba_single_us"] / out[50]["aba_single_us"]}  # fmt: skip
    if "pin_aba_single_us" in r:
        summary["n100_single_over_pin"] = r["aba_single_us"] / r["pin_aba_single_us"]
        summary["n100_batched_per_env_over_pin"] = r["aba_batch_per_env_us"] / r["pin_aba_single_us"]
    return summary


def mujoco_step(repeats: int, steps: int) -> dict | None:
    """InvertedDoublePendulum-v5's step time (and Acrobot-v1's, same run) and its integration error."""
    try:
        env = gym.make("InvertedDoublePendulum-v5")
    except Exception as e:  # mujoco not installed
        return {"skipped": f"{type(e).__name__}: {e}"}
    acro = gym.make("Acrobot-v1")
    rng = np.random.default_rng(0)
    t_m, t_a = [], []
    for _ in tqdm(range(repeats), desc="mujoco step"):  # interleaved, as in the single section
        t_m.append(time_steps(env, list(rng.uniform(-1, 1, (steps, 1)).astype(np.float32)), 400))
        t_a.append(time_steps(acro, [int(a) for a in rng.integers(0, 3, steps)], 400))
    return {"median_step_us": float(np.median(t_m)) * 1e6, "acrobot_us": float(np.median(t_a)) * 1e6,
            "error": mujoco_step_error(env)}  # fmt: skip


def mujoco_step_error(env, n_states: int = 50, refine: int = 200) -> dict:
    """Largest state error of InvertedDoublePendulum-v5 over one control step at its defaults
    (RK4, ``frame_skip`` steps of ``timestep``), against the same MuJoCo model integrated by RK4
    at ``timestep / refine``; that reference's own error is estimated against ``timestep / (2 refine)``.

    States as in :func:`step_errors` (angles in [-pi, pi], rates in [-4, 4] rad/s), the cart
    within [-0.3, 0.3] m at [-1, 1] m/s so that its joint limit stays inactive (checked).
    """
    import mujoco

    u = env.unwrapped
    model, frame_skip, h = u.model, u.frame_skip, u.model.opt.timestep

    def fine(k: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
        m = mujoco.MjModel.from_xml_path(u.fullpath)
        m.opt.timestep, m.opt.integrator = h / k, mujoco.mjtIntegrator.mjINT_RK4
        return m, mujoco.MjData(m)

    runs = {k: fine(k) for k in (refine, 2 * refine)}
    runs[1] = (model, mujoco.MjData(model))
    rng = np.random.default_rng(1)
    err, err_ref, limit_active = 0.0, 0.0, 0
    for _ in range(n_states):
        qpos = np.r_[rng.uniform(-0.3, 0.3), rng.uniform(-np.pi, np.pi, 2)]
        qvel = np.r_[rng.uniform(-1, 1), rng.uniform(-4, 4, 2)]
        ctrl = rng.uniform(-1, 1, 1)
        end = {}
        for k, (m, d) in runs.items():
            mujoco.mj_resetData(m, d)
            d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, ctrl
            for _ in range(frame_skip * k):
                mujoco.mj_step(m, d)
                limit_active += d.nefc > 0
            end[k] = np.r_[d.qpos, d.qvel]
        err = max(err, float(np.max(np.abs(end[1] - end[2 * refine]))))
        err_ref = max(err_ref, float(np.max(np.abs(end[refine] - end[2 * refine]))))
    return {"dt": frame_skip * h, "timestep": h, "frame_skip": frame_skip, "integrator": "RK4",
            "max_state_error_per_step": err, "reference_error_estimate": err_ref,
            "steps_with_active_constraints": int(limit_active)}  # fmt: skip


def sb3_throughput(
    n_envs_list: list[int],
    samples: int,
    iterations: int,
    threads: list[int],
    repeats: int,
    env_id: str = "mbs_envs/Planar2R-v0",
) -> dict:
    """PPO env-steps per second on ``env_id``, adapter against ``make_vec_env`` of single envs, for
    each torch thread count and ``n_envs``: medians over ``repeats`` interleaved timings.

    Both sides train the same PPO (MlpPolicy, one epoch over ``samples`` env-steps
    per iteration in minibatches of ``samples / 4``, ``n_steps = samples / n_envs``):
    only the envs differ. Timed: ``iterations`` iterations of the whole ``learn``,
    and rollouts alone (policy sampling plus env steps, ``samples`` env-steps). The
    envs run on one thread; torch uses ``threads`` (its default is one per core).
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    from mbs_envs.envs.sb3 import make_sb3_vec_env

    def rollout(model, venv, n_steps):
        obs = venv.reset()
        t0 = time.perf_counter()
        for _ in range(n_steps):
            action, _ = model.predict(obs, deterministic=False)
            obs, _, _, _ = venv.step(action)
        return (time.perf_counter() - t0) / samples

    def learn(model):
        t0 = time.perf_counter()
        model.learn(iterations * samples, reset_num_timesteps=False)
        return (time.perf_counter() - t0) / (iterations * samples)

    default_threads = torch.get_num_threads()
    out = {}
    for n_threads, n_envs in tqdm([(t, n) for t in threads for n in n_envs_list], desc="sb3"):
        torch.set_num_threads(n_threads)
        n_steps = samples // n_envs
        venvs = {
            "SB3 make_vec_env (DummyVecEnv of single envs)": make_vec_env(env_id, n_envs=n_envs, seed=0),
            "mbs_envs SB3 adapter (batched)": make_sb3_vec_env(env_id, n_envs=n_envs, seed=0),
        }
        models = {
            k: PPO("MlpPolicy", v, n_steps=n_steps, batch_size=samples // 4, n_epochs=1, seed=0, device="cpu")
            for k, v in venvs.items()
        }
        for model in models.values():
            model.learn(samples)  # warm-up
        times: dict[str, dict[str, list[float]]] = {k: {"learn": [], "rollout": []} for k in venvs}
        for _ in range(repeats):  # interleaved, so that both sides see the same machine
            for k in venvs:
                times[k]["learn"].append(learn(models[k]))
                times[k]["rollout"].append(rollout(models[k], venvs[k], n_steps))
        for venv in venvs.values():
            venv.close()
        res = {
            k: {f"{what}_env_steps_per_s": 1 / float(np.median(t)) for what, t in v.items()} for k, v in times.items()
        }
        a, b = res.values()
        out[f"{n_threads} torch threads, {n_envs} envs"] = {"torch_threads": n_threads, "n_envs": n_envs, "n_steps": n_steps, "results": res,
                       "ratio_learn": b["learn_env_steps_per_s"] / a["learn_env_steps_per_s"],
                       "ratio_rollout": b["rollout_env_steps_per_s"] / a["rollout_env_steps_per_s"]}  # fmt: skip
    torch.set_num_threads(default_threads)
    return {"env_id": env_id, "samples_per_iteration": samples, "iterations": iterations, "repeats": repeats,
            "torch_default_threads": default_threads, "runs": out}  # fmt: skip


def sb3_scenes(env_ids: list[str], out: pathlib.Path) -> dict:
    """:func:`sb3_throughput` per scene at 1024 envs with torch's default threads (``--sb3-only``)."""
    out.mkdir(parents=True, exist_ok=True)
    result = {env_id: sb3_throughput([1024], 16384, 2, [_torch_threads()], 5, env_id) for env_id in env_ids}
    (out / "sb3_scenes.json").write_text(json.dumps(result, indent=2, default=float))
    for env_id, r in result.items():
        for name, run in r["runs"].items():
            print(
                f"{env_id}, {name}: PPO learn {run['ratio_learn']:.1f}x make_vec_env, rollouts {run['ratio_rollout']:.1f}x "
                f"({run['results']})"
            )
    print(f"written to {out}/sb3_scenes.json")
    return result


def add_zero_cost_env_bound(result: dict) -> None:
    """For PPO runs at the batched section's ``num_envs``: the largest whole-``learn`` ratio
    any env could reach, ``t_baseline / (t_adapter - t_env)`` per env-step, where
    ``t_env`` is the batched step measured in the same run (PPO's own cost stays)."""
    b = result["batched"]
    t_env = b["per_env_step_us"]["Planar2R-v0 vector"] * 1e-6
    for q in result["sb3"]["runs"].values():
        if q["n_envs"] == b["num_envs"]:
            base, ours = (1 / v["learn_env_steps_per_s"] for v in q["results"].values())
            q["ratio_learn_zero_cost_env_bound"] = base / (ours - t_env)


def _torch_threads() -> int:
    import torch

    return torch.get_num_threads()


def run(out: pathlib.Path, quick: bool = False) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    reps = 3 if quick else 11
    result = {
        "machine": {"python": platform.python_version(), "processor": platform.processor(), "numpy": np.__version__},
        "quick": quick,
        "single": single_step(reps, 200 if quick else 1000),
        "batched": batched_step(1024, reps, 20 if quick else 100),
        "chain": chain_dynamics(),
        "mujoco": mujoco_step(reps, 200),
        "sb3": sb3_throughput(
            [16, 256] if quick else [64, 256, 1024],
            4096 if quick else 16384,
            1 if quick else 2,
            [1] if quick else sorted({1, _torch_threads()}),
            reps if quick else 5,
        ),
    }
    add_zero_cost_env_bound(result)
    (out / "bench.json").write_text(json.dumps(result, indent=2, default=float))
    plot(result, out / "bench.png")
    print(report(result))
    print(f"written to {out}/bench.json and bench.png")
    return result


def report(r: dict) -> str:
    s, b, c, p = r["single"], r["batched"], r["chain"], r["sb3"]
    lines = [
        f"single step [us]: {s['median_step_us']}  Planar2R / Acrobot = {s['ratio_planar2r_to_acrobot']:.2f} (target <= 0.5)",
        f"error per control step: Acrobot {s['error']['acrobot_max_state_error_per_step']:.2e} (dt {s['error']['acrobot_dt']}), "
        f"Planar2R {s['error']['planar2r_max_state_error_per_step']:.2e} (dt {s['error']['planar2r_dt']}): "
        f"{s['error']['ratio_acrobot_to_planar2r']:.3g}x lower (target >= 100)",
        f"  at Acrobot's control step (dt 0.2 s, {AT_ACROBOT_DT['substeps']} RK4 substeps: the default 5 ms physics step): "
        f"{s['ratio_planar2r_at_acrobot_dt_to_acrobot']:.2f}x Acrobot's time, error {s['error']['planar2r_at_acrobot_dt']['max_state_error_per_step']:.2e}, "
        f"{s['error']['planar2r_at_acrobot_dt']['ratio_acrobot_to_planar2r']:.3g}x lower",
        f"batched per env-step at {b['num_envs']} [us]: "
        + ", ".join(f"{k} {v:.3f}" for k, v in b["per_env_step_us"].items()),
        "  ratio to CartPole: "
        + ", ".join(f"{k} {v:.2f}" for k, v in b["ratio_to_cartpole"].items())
        + " (target <= 3)",
        f"  the step's sines and cosines of {b['trig_floor']['angles_per_member']} angles per member alone: by libm "
        f"{b['trig_floor']['libm_per_env_step_us']:.3f} us ({b['trig_floor']['libm_ratio_to_cartpole']:.2f}x CartPole's whole step), "
        f"by the SIMD sincos {b['trig_floor']['simd_sincos_per_env_step_us']:.3f} us ({b['trig_floor']['simd_sincos_ratio_to_cartpole']:.2f}x)",
        f"chain N=100: ABA single {c['rows'][100]['aba_single_us']:.1f} us, per env in batch {c['rows'][100]['aba_batch_per_env_us']:.2f} us; "
        f"t(400)/t(50) batched {c['t400_over_t50_batched']:.2f}, single {c['t400_over_t50_single']:.2f} (target <= 12)",
    ]
    if "n100_single_over_pin" in c:
        lines.append(
            f"  vs Pinocchio aba: single {c['n100_single_over_pin']:.2f}x (target <= 3), batched per env {c['n100_batched_per_env_over_pin']:.2f}x (target <= 1)"
        )
    m = r["mujoco"]
    if "skipped" in m:
        lines.append(f"mujoco: skipped ({m['skipped']})")
    else:
        e = m["error"]
        lines.append(
            f"InvertedDoublePendulum-v5 step: {m['median_step_us']:.1f} us (Acrobot-v1 {m['acrobot_us']:.1f} us in the same section); "
            f"Planar2R-v0 / IDP: {s['median_step_us']['Planar2R-v0'] / m['median_step_us']:.2f}x"
        )
        lines.append(
            f"  error per control step (dt {e['dt']:g} s, RK4 {e['frame_skip']} x {e['timestep']:g} s): {e['max_state_error_per_step']:.1e} "
            f"(reference error {e['reference_error_estimate']:.0e}; steps with active constraints {e['steps_with_active_constraints']})"
        )
    for n, q in p["runs"].items():
        lines.append(
            f"PPO env-steps/s, {n}: "
            + "; ".join(
                f"{k}: learn {v['learn_env_steps_per_s']:.0f}, rollout {v['rollout_env_steps_per_s']:.0f}"
                for k, v in q["results"].items()
            )
        )
        lines.append(
            f"  adapter / make_vec_env: learn {q['ratio_learn']:.2f}x, rollout {q['ratio_rollout']:.2f}x (target >= 10)"
            + (
                f"; learn with a zero-cost env at most {q['ratio_learn_zero_cost_env_bound']:.2f}x"
                if "ratio_learn_zero_cost_env_bound" in q
                else ""
            )
        )
    return "\n".join(lines)


def plot(r: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 4, figsize=(20, 4.5))
    s = dict(r["single"]["median_step_us"])
    if "median_step_us" in r["mujoco"]:
        s["InvertedDouble-\nPendulum-v5 (MuJoCo)"] = r["mujoco"]["median_step_us"]
    axes[0].bar(
        range(len(s)), list(s.values()), tick_label=[k.replace(" (", "\n(").replace(" at ", "\nat ") for k in s]
    )
    axes[0].set_ylabel("median step [us]")
    axes[0].set_title("single env step")
    b = r["batched"]["per_env_step_us"]
    axes[1].bar(range(len(b)), list(b.values()), tick_label=[k.replace(" vector", "\nvector") for k in b])
    axes[1].set_ylabel("per env-step [us]")
    axes[1].set_title(f"batched, {r['batched']['num_envs']} envs")
    rows = r["chain"]["rows"]
    ns = sorted(rows, key=int)
    axes[2].loglog([int(n) for n in ns], [rows[n]["aba_single_us"] for n in ns], "o-", label="ABA single")
    axes[2].loglog([int(n) for n in ns], [rows[n]["aba_batch_per_env_us"] for n in ns], "o-", label="ABA per env (256)")
    if "pin_aba_single_us" in rows[ns[0]]:
        axes[2].loglog([int(n) for n in ns], [rows[n]["pin_aba_single_us"] for n in ns], "s--", label="Pinocchio aba")
    axes[2].set_xlabel("N links")
    axes[2].set_ylabel("[us]")
    axes[2].legend()
    axes[2].set_title("chain forward dynamics")
    runs = list(r["sb3"]["runs"].values())
    for n_threads in sorted({q["torch_threads"] for q in runs}):
        sel = [q for q in runs if q["torch_threads"] == n_threads]
        ns = [q["n_envs"] for q in sel]
        axes[3].semilogx(
            ns, [q["ratio_learn"] for q in sel], "o-", base=2, label=f"whole learn, torch {n_threads} thr."
        )
        axes[3].semilogx(
            ns, [q["ratio_rollout"] for q in sel], "s--", base=2, label=f"rollouts, torch {n_threads} thr."
        )
    axes[3].axhline(10, color="k", ls=":", label="target")
    axes[3].set_xlabel("n_envs")
    axes[3].set_ylabel("adapter / make_vec_env env-steps per s")
    axes[3].legend()
    axes[3].set_title("PPO throughput ratio")
    for ax in axes[:2]:
        ax.tick_params(axis="x", labelsize=7)
        ax.set_yscale("log")  # the numpy path is 20-40x the compiled one
    save(fig, path)
