"""Robustness sweeps: one batched run per axis, each member one value of the axis.

A sweep perturbs the closed loop along six axes, as the DFKI benchmark's robustness v2 does
(:mod:`mbs_envs.studies.dfki` gives its ranges; ``scripts/robustness.py`` gives ranges for every
scene). Every axis is one :class:`Perturbation` batch on a vector env whose members hold the axis's
values, so a whole axis is one rollout:

- **model**: each member its own plant parameters (the vector env's ``member_params``);
- **measurement noise**: Gaussian noise of std ``sigma`` on the observation entries ``noise_index``
  (e.g. the velocities), drawn afresh at every control step;
- **torque noise**: Gaussian noise of std ``sigma`` [N m] added to the commanded torque, then the
  actuator limit;
- **torque response**: a first-order actuator, ``u_k = u_{k-1} + r (u_cmd,k - u_{k-1})`` with
  responsiveness ``r`` (1: ideal; below: a lag; above: overshoot), from ``u_{-1} = 0``;
- **time delay**: the controller sees the observation of ``d`` control steps earlier (the first
  observation until then);
- **perturbations**: torque pulses ``tau(t)`` on every joint, applied at each step as the impulse
  ``tau(t_k) dt`` (:meth:`~mbs_envs.envs.vector.MBSVectorEnv.apply_impulse`: first-order operator
  splitting; the pulses are 25 steps wide or more at the protocol's rate).

The rollout records every member's final state and whether it ended early; the caller's success
rule judges them. Actions go through the env as the agent's normalized actions (``u / u_max``).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from ..envs.perturbations import actuated, delayed, gaussian_pulses, random_pulses, with_noise  # noqa: F401


@dataclasses.dataclass(frozen=True)
class Perturbation:
    """Per-member settings of one batched rollout (every array has one entry per member; None: unperturbed).

    Attributes
    ----------
    noise_sigma : ndarray (n,), optional
        Std of the measurement noise on the observation entries ``noise_index``.
    noise_index : tuple of int
        Observation entries the noise reaches (empty: all).
    torque_sigma : ndarray (n,) or (n, nu), optional
        Std of the torque noise [N m], per member or per member and input.
    response : ndarray (n,), optional
        Actuator responsiveness ``r`` (module docstring).
    delay : ndarray of int (n,), optional
        Observation delay in control steps.
    pulses : ndarray (n, steps, nv), optional
        Disturbance torque of every joint at every control step [N m].
    """

    noise_sigma: np.ndarray | None = None
    noise_index: tuple[int, ...] = ()
    torque_sigma: np.ndarray | None = None
    response: np.ndarray | None = None
    delay: np.ndarray | None = None
    pulses: np.ndarray | None = None

    def rows(self, members: slice) -> Perturbation:
        """The settings of the members ``members`` (a slice of the batch) alone."""
        return dataclasses.replace(self, **{f.name: getattr(self, f.name)[members] for f in dataclasses.fields(self)
                                            if f.name != "noise_index" and getattr(self, f.name) is not None})  # fmt: skip


def run(venv: Any, policy: Any, seeds: list[int], p: Perturbation, noise_seed: int = 0, deterministic: bool = True,
        record: bool = False, batch: tuple[int, int] | None = None) -> dict[str, Any]:  # fmt: skip
    """One perturbed episode per member of ``venv`` (``autoreset_mode="Disabled"``, a ``max_episode_steps``).

    ``batch = (total, first)``: these members are the rows ``first .. first + n`` of a batch of ``total`` whose
    noise is drawn as one (``noise_seed``'s draws for all ``total`` rows at each step, these rows taken), so a part
    of a batch run on its own sees what it sees in the whole batch: the same episodes, bit for bit, where the policy's
    action for a member does not depend on the other members to the bit (the model-based controllers here: tested).
    A neural network's does, in its last bits: a batched matrix product's blocking follows the batch size, and a
    closed loop amplifies the difference (a PPO agent on the DFKI acrobot ends elsewhere in parts than in one batch).

    Returns
    -------
    dict
        ``q`` (n, nq) and ``v`` (n, nv): each member's state when its episode ended; ``terminated`` (n,):
        it ended early (diverged); ``steps`` (n,): the control steps it ran; with ``record``, ``episodes``:
        one :class:`~mbs_envs.studies.evaluation.Episode` per member (what the plant did: the applied,
        perturbed torques in ``u``), for the scene's own scoring.
    """
    from .evaluation import episodes_from_rows, record_step

    base = venv.unwrapped
    n, steps = len(seeds), base.max_episode_steps
    if base.num_envs != n or steps is None:
        raise ValueError(f"venv needs {n} members and a max_episode_steps, has {base.num_envs} and {steps}")
    u_max = np.asarray(base.env.u_max, float)
    total, first = (n, 0) if batch is None else (int(batch[0]), int(batch[1]))
    if not 0 <= first <= total - n:
        raise ValueError(f"batch: {n} members from row {first} do not fit in a batch of {total}")
    rng = np.random.default_rng(noise_seed)

    def normal(k: int) -> np.ndarray:  # (n, k) standard normals: these members' rows of the whole batch's draw
        z = rng.standard_normal((total, k))
        return z if batch is None else z[first : first + n]

    obs, _ = base.reset(seed=list(seeds))
    delay = np.zeros(n, int) if p.delay is None else np.asarray(p.delay, int)
    history = np.empty((int(delay.max()) + 1,) + obs.shape, obs.dtype)  # a ring of the last observations
    applied = np.zeros((n, base.model.nu))
    q_end, v_end = base.q, base.v
    ran = np.full(n, steps)
    done = np.zeros(n, bool)
    terminated_any = np.zeros(n, bool)
    state, start = None, np.ones(n, bool)
    dt = float(base.env.dt)
    rows: dict[str, list] = {"t": [], "e": [], "u": [], "r": [], "dt": [], "div": []}
    for k in range(steps):
        history[k % len(history)] = obs
        seen = delayed(history, k, delay) if delay.any() else obs
        if p.noise_sigma is not None:
            idx = list(p.noise_index) or slice(None)
            seen = with_noise(seen, idx, np.asarray(p.noise_sigma)[:, None] * normal(seen[:, idx].shape[1]))
        tic = time.perf_counter()
        action, state = policy.predict(seen, state=state, episode_start=start, deterministic=deterministic)
        if record:
            rows["dt"].append((time.perf_counter() - tic) / n)
        start = np.zeros(n, bool)
        u = np.clip(np.asarray(action, float).reshape(n, -1), -1.0, 1.0) * u_max
        noise = None
        if p.torque_sigma is not None:
            sigma = np.asarray(p.torque_sigma, float)
            noise = (sigma[:, None] if sigma.ndim == 1 else sigma) * normal(u.shape[1])
        applied = actuated(u, applied, u_max, noise, None if p.response is None else np.asarray(p.response))
        if p.pulses is not None:
            base.apply_impulse(np.where(done[:, None], 0.0, p.pulses[:, k] * dt))
        obs, reward, terminated, truncated, info = base.step((applied / u_max).astype(np.float32))
        if record:
            record_step(rows, reward, info)
        newly = ~done & (terminated | truncated)
        q_now, v_now = base.q, base.v
        q_end[newly], v_end[newly] = q_now[newly], v_now[newly]
        ran[newly] = k + 1
        terminated_any |= newly & terminated
        done |= newly
        if done.all():
            break
    out = {"q": q_end, "v": v_end, "terminated": terminated_any, "steps": ran}
    if record:
        out["episodes"] = episodes_from_rows(rows, ran, terminated_any)
    return out


def plot_success(results: dict[str, list[dict[str, Any]]], axes: tuple[str, ...], title: str, path: Any) -> None:
    """Success against each axis' value, one line per policy (the model axis: the share per parameter; the
    perturbations: one share per policy), 2 x 3 panels; policy ``j``'s line is drawn ``0.012 j`` higher so
    equal lines stay apart.

    ``results``: policy name -> its sweeps (one per training seed), each ``{axis: {"values", "success"}}``;
    the shares pool the seeds and training seeds of a value.
    """
    from .plotting import pyplot, save

    plt = pyplot()
    fig, panels = plt.subplots(2, 3, figsize=(12, 6.5))
    width = 0.8 / max(len(results), 1)
    for ax, axis in zip(panels.flat, axes):
        for j, (name, sweeps) in enumerate(results.items()):
            values = [v for r in sweeps for v in r[axis]["values"]]
            ok = np.concatenate([np.asarray(r[axis]["success"], float) for r in sweeps])
            if axis == "model":
                keys = list(dict.fromkeys(v[0] for v in values))
                share = [ok[[v[0] == k for v in values]].mean() for k in keys]
                ax.bar(np.arange(len(keys)) + width * (j - (len(results) - 1) / 2), share, width=width, label=name)
                ax.set_xticks(np.arange(len(keys)), keys, fontsize=7)
            elif axis == "perturbations":
                ax.bar(j, ok.mean(), label=name)
                ax.set_xticks([])
            else:
                x = np.asarray(values, float)
                grid = np.unique(x)
                ax.plot(
                    grid, [ok[x == g].mean() + 0.012 * j for g in grid], marker="o", ms=3, label=name
                )  # offset: lines stay apart
        ax.set_title(axis, fontsize=9)
        ax.set_ylim(-0.05, 1.05 + 0.012 * len(results))  # room for the offset lines at 1
    panels.flat[0].set_ylabel("success")
    panels.flat[3].set_ylabel("success")
    handles, labels = panels.flat[1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5), fontsize=7)
    fig.suptitle(title)
    save(fig, path, rect=(0, 0.07, 1, 0.96))
