"""Identify, plan, track: a swing-up along a trajectory optimized on the identified plant, stabilized by
time-varying LQR, then the upright LQR (Acrobot, Pendubot).

Per member of the batch, in three phases:

0. **Identify while pumping** (:class:`controllers.adaptive_swingup.AdaptiveSwingUpLQR`'s laws): energy
   pumping on the model identified online from the arm's energy balance, with the extended Kalman filter
   where observations are noisy, for ``plan_time`` seconds.
1. **Plan and track**: from the (estimated) state, a swing-up trajectory optimized under the torque limit
   on the identified model and the time-varying LQR along it (:mod:`controllers.trajectory`); the input is
   ``u = U_k + K_k (x - X_k)``, on knots ``plan_step`` apart (the control steps of our scenes; every fifth on the
   DFKI protocol's, ``X`` interpolated between knots). The member plans again, from where it is, when it leaves the
   plan's funnel (an angle more than ``funnel`` rad off the planned one).
2. **Balance**: at the plan's end (upright, where its terminal cost put it), the upright LQR of the
   identified model. Where the LQR's cost-to-go ``dx^T S dx`` exceeds ``drop`` the member plans again.

**Settings.** The prior toward the nominal base parameters is 0.1 J^2 (not the adaptive controller's 1: on tuning
seeds 20000-20019 the pendubot at +20 % held 18 of 20 episodes with it against 8 of 20), the time-varying LQR's input
weight 1 (against 100, both with the prior at 1: acrobot 100/80/70 % nominal/+20/-20 against 100/65/70 %, pendubot
alike), the upright LQR's input weight 10 on both scenes (``scripts/tune.py --refine-only``, tuning seeds 20000-20019,
nominal and +-20 %: failures 0 % on the acrobot against 3-7 % for 1, 100, 1e3, 1e4 and the adaptive controller's tuned
1e4; 2 % on the pendubot against 5-27 %) and the guess's patience 5 s (tuning seeds 20000-20039: acrobot 97/88/88 % against 97/78/80 % without
patience, pendubot 100/93/97 % against 100/80/100 %). The others (a 10-s horizon, 100 iterations, refinement every
0.5 s, 85 % of the torque limit, the funnel and the catch test) were set while building it; a horizon of 3 s planned
too rarely (3 of 10 nominal episodes while building, with 30 iterations). These settings were tuned on our scenes
(control steps of 0.01 s, where a plan's knots are the control steps) with the earlier, scalar map, whose plans differ
from today's in their last bits. On the DFKI protocol (2-ms control steps) a plan's knots are 0.01 s apart as there
(``plan_step``): a plan there costs about 0.09 s of one core on average (0.27 s on every control step, 0.56 s before the
planner's map ran on SIMD lanes; :mod:`controllers.trajectory`, docs/performance.md).

**Memory** (SB3's ``state``): a tuple ``(row, plan)``: ``row`` (n, :data:`ROW_SIZE`) holds the adaptive
controller's memory (identification, filter, last inputs) followed by the phase, the step in the plan, the
plan's length, the steps since the episode started and those since the last plan (or attempt); ``plan`` (n, :attr:`plan_size`) the plan's inputs,
states and gains. ``plan`` is only replaced (never written in place) when a member plans, so a state
passed to ``predict`` is never changed by it.
"""

from __future__ import annotations

import concurrent.futures
import os
from typing import Any

import numpy as np

from mbs_envs import validation as check
from mbs_envs.envs.swingup import Q_UP

from . import identification as ident
from . import trajectory as traj
from .control_map import state_error
from .adaptive_swingup import K_, MODE, S_, STATE_SIZE, THETA, AdaptiveSwingUpLQR

#: columns after the adaptive controller's: phase (0 pump, 1 track, 2 balance), step in the plan, plan length,
#: steps since the episode started, steps since the last plan (or attempt)
PHASE, STEP, LENGTH, CLOCK, SINCE = range(STATE_SIZE, STATE_SIZE + 5)
ROW_SIZE = STATE_SIZE + 5
#: the plan's terminal weight per unit ``w_T`` (angles [rad^-2], rates [s^2 rad^-2])
TERMINAL = np.diag([1.0, 1.0, 0.1, 0.1])
#: the pumping gains searched for the initial guess (k_q [1/s^2], k_v [1/s], k_E [1/(J s)])
PUMPING_GRID = np.array(np.meshgrid([2.0, 5.0, 10.0, 20.0, 50.0], [0.5, 1.0, 2.0, 5.0, 10.0], [1.0, 2.0, 4.0, 8.0, 16.0]), float).reshape(3, -1).T


def plan_threads() -> int:
    """How many members plan at once: ``$MBS_ENVS_PLAN_THREADS`` if set (>= 1), else the cores this process may
    run on."""
    value = os.environ.get("MBS_ENVS_PLAN_THREADS")
    if value is None:
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        n = int(value)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"MBS_ENVS_PLAN_THREADS must be a whole number >= 1, got {value!r}")
    return n


#: the planning threads, per process (a forked child's copy of its parent's pool has no threads) and size
_POOL: dict[tuple[int, int], concurrent.futures.ThreadPoolExecutor] = {}


def thread_map(f: Any, items: list) -> list:
    """``[f(x) for x in items]``, on up to :func:`plan_threads` threads (a pool kept per process); in order."""
    n = min(plan_threads(), len(items))
    if n <= 1:
        return [f(item) for item in items]
    key = (os.getpid(), n)
    pool = _POOL.get(key)
    if pool is None:
        pool = _POOL[key] = concurrent.futures.ThreadPoolExecutor(max_workers=n, thread_name_prefix="plan")
    return list(pool.map(f, items))


class PlannedSwingUp(AdaptiveSwingUpLQR):
    """Identify while pumping, then track a trajectory optimized on the identified plant (module docstring).

    Parameters
    ----------
    env, k_q, k_v, k_E, lqr_r, window, prior, obs_noise, process_noise, gate
        As :class:`AdaptiveSwingUpLQR` (the pumping of phase 0, the LQR's input weight, the identification
        and the filter); by default from the ``"identified iLQR + TVLQR"`` entry of ``controllers/tuned.json``
        (its own ``lqr_r`` picked by ``scripts/tune.py``, :func:`mbs_envs.studies.tuning.planner_grid`).
    catch, release
        Validated and kept for the shared gains entry, unused: this controller's catch is the simulated
        region (``catch_time``, ``catch_tol``), not a level of ``x^T S x``.
    plan_time : float
        Seconds of identification before the first attempt to plan (>= 0).
    horizon : float
        The longest plan [s].
    tail : float
        Seconds the plan continues after the pumping guess's closest approach to upright.
    iterations, refine_iterations : int
        iLQR iterations of a new plan and of a plan refined from where the arm is.
    w_u, w_T, w_x : float
        The plan's effort weight [1/(N m)^2 s], and the scales of its terminal and running state weights
        (:data:`TERMINAL` times each; :func:`controllers.trajectory.ilqr`'s objective). ``w_x = 0``: a
        running cost quadratic in wrapped angles far from upright made plans worse while building it.
    margin : float
        The share of the torque limit the plan may use (the rest is the feedback's).
    accept : float
        A plan is taken when it ends within this distance of upright (largest wrapped entry [rad, rad/s]).
    retry, refine_every : float
        Seconds between attempts to plan while pumping, and between refinements of the plan being tracked.
    funnel : float
        Largest angle off the plan [rad] before the member plans afresh.
    drop : float
        Largest angle off upright [rad] before a balancing member plans afresh.
    track_r : float
        The time-varying LQR's input weight [(N m)^-2] (its state weight is the upright LQR's ``Q``).
    catch_time, catch_tol : float
        A member not balancing is handed to the upright LQR where, simulated on the identified model from the
        current state for ``catch_time`` [s], the saturated LQR ends within ``catch_tol`` of upright (rad, rad/s;
        checked only within ``drop`` of upright): the LQR's region of attraction under the torque limit, sampled
        at the states the arm visits.
    plan_step, plan_h : float
        The plan's time grid [s]: its knots ``stride = max(1, round(plan_step / dt))`` control steps apart (inputs
        held, gains and states per knot, the state between knots interpolated for the feedback), its model stepped
        by RK4 in ``ceil(stride dt / plan_h)`` sub-steps (where ``stride`` is 1, the env's own sub-steps: our
        swing-up scenes, ``dt = 0.01``, plan on their control steps as before). On the DFKI protocol (``dt =
        0.002``) a plan's knots are 0.01 s apart, as on the scenes where this controller was built: a fifth of the
        stages, 2 RK4 steps per knot.
    patience : float
        [s]: the initial guess trades a closer approach to upright against an earlier one, ``e`` times the
        cost-to-go for ``patience`` seconds sooner (:func:`controllers.trajectory.pumping_search`).
    """

    tuned_name = "identified iLQR + TVLQR"

    def __init__(self, env: Any, k_q: Any = None, k_v: Any = None, k_E: Any = None, catch: Any = None, release: float = 4.0,
                 lqr_r: Any = None, window: int = 10,
                 prior: float = 0.1, obs_noise: float = 0.01, process_noise: Any = ((1e-4, 1e-2), (3e-4, 3e-2)),
                 plan_time: float = 3.0, horizon: float = 10.0, tail: float = 0.5, iterations: int = 100, refine_iterations: int = 10,
                 w_u: float = 0.1, w_T: float = 1e4, margin: float = 0.85, accept: float = 0.05, retry: float = 1.0,
                 refine_every: float = 0.5, funnel: float = 0.5, drop: float = 0.3, patience: float = 5.0, track_r: float = 1.0, w_x: float = 0.0, catch_time: float = 3.0,
                 catch_tol: float = 0.01, plan_step: float = 0.01, plan_h: float = 0.005, gate: Any = None):  # fmt: skip
        # a catch level only for the inherited switching rule, which this controller does not use (module docstring)
        catch = 1.0 if catch is None else catch
        super().__init__(env, k_q=k_q, k_v=k_v, k_E=k_E, catch=catch, release=release, lqr_r=lqr_r, window=window, prior=prior, obs_noise=obs_noise,
                         process_noise=process_noise, gate=gate)  # fmt: skip
        def steps(t: Any, name: str, positive: bool = False, step: float = self.dt) -> int:  # a duration [s] in steps of ``step``
            return int(round(check.real(t, name, 0.0, 1e4, low_open=positive) / step))

        # the plan's grid: ``stride`` control steps per knot, its model stepped by RK4 in steps of at most ``plan_h``
        self.stride = max(1, steps(plan_step, "plan_step", positive=True))
        h = check.real(plan_h, "plan_h", 0.0, 1.0, low_open=True)
        self.plan_dt = self.stride * self.dt
        self.plan_substeps = self.substeps if self.stride == 1 else max(1, int(np.ceil(round(self.plan_dt / h, 9))))
        self.plan_steps = steps(plan_time, "plan_time")
        self.max_steps = max(2, steps(horizon, "horizon", positive=True, step=self.plan_dt))
        self.tail = min(steps(tail, "tail", step=self.plan_dt), self.max_steps - 1)
        self.patience = max(1, steps(patience, "patience", step=self.plan_dt))
        self.retry_steps = max(1, steps(retry, "retry", positive=True))
        self.refine_steps = max(1, steps(refine_every, "refine_every", positive=True))
        self.iterations = check.integer(iterations, "iterations", 0, 10**6)
        self.refine_iterations = check.integer(refine_iterations, "refine_iterations", 0, 10**6)
        self.w_u = check.positive(w_u, "w_u")
        self.w_T = check.positive(w_T, "w_T")
        self.P_T = self.w_T * TERMINAL
        self.W = check.nonnegative(w_x, "w_x") * TERMINAL
        self.track_r = check.positive(track_r, "track_r")
        self.catch_steps = max(10, steps(catch_time, "catch_time"))
        self.catch_tol = check.positive(catch_tol, "catch_tol")
        self.margin = check.real(margin, "margin", 0.0, 1.0, low_open=True)
        self.accept = check.positive(accept, "accept")
        self.funnel = check.positive(funnel, "funnel")
        self.drop = check.positive(drop, "drop")
        self.goal = np.concatenate([Q_UP, np.zeros(2)])
        H = self.max_steps
        self.plan_size = H + 4 * (H + 1) + 4 * H

    def _views(self, plan: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(U (n, H), X (n, H + 1, 4), K (n, H, 4))`` views of the plan rows."""
        n, H = len(plan), self.max_steps
        return plan[:, :H], plan[:, H : H + 4 * (H + 1)].reshape(n, H + 1, 4), plan[:, H + 4 * (H + 1) :].reshape(n, H, 4)

    def reference(self, X: np.ndarray, j: np.ndarray) -> np.ndarray:
        """The planned state at control step ``j`` (n,) of each member's plan ``X`` (n, H + 1, 4): the knot
        ``X[k]``, ``k = j // stride``, or between knots ``X[k] + f (X[k + 1] - X[k])`` (angle differences wrapped),
        ``f = (j mod stride) / stride``; ``j`` at most ``H stride``."""
        idx = np.arange(len(X))
        k = np.minimum(j // self.stride, self.max_steps)
        if self.stride == 1:
            return X[idx, k]
        f = (j - k * self.stride) / self.stride
        between = f > 0.0
        out = X[idx, k]
        if between.any():
            b = np.flatnonzero(between)
            nxt = X[b, np.minimum(k[b] + 1, self.max_steps)]
            out[b] = out[b] + f[b, None] * state_error(nxt, out[b])
        return out

    def kernel_columns(self, row: np.ndarray, members: np.ndarray) -> list[np.ndarray]:
        """The identified model of each of ``members`` as the kernels take it: a contiguous column ``(P, 1)`` each."""
        return [np.ascontiguousarray(t[:, None]) for t in self.kernel_theta(row[members, THETA])]

    def make_plans(self, row: np.ndarray, plan: np.ndarray, members: np.ndarray, x: np.ndarray, refine: np.ndarray) -> np.ndarray:
        """Plan for ``members`` from ``x`` (n, 4) on their identified models: afresh, or where ``refine`` (per
        member listed) from the rest of the plan being tracked. Writes ``row`` (phase, step, length, since) in
        place and returns a new plan array (the one passed in untouched). Members plan on :func:`plan_threads`
        threads at once (the compiled planner releases the GIL; each member's plan is its own, so the result does
        not depend on how many)."""
        plan = plan.copy()
        Us, Xs, Ks = self._views(plan)
        u_max, driven, R = float(self.u_max[0]), self.driven, self.track_r

        def one(j: int, i: int, th: np.ndarray) -> tuple:
            U_new, X_new, K_new = np.empty(self.max_steps), np.empty((self.max_steps + 1, 4)), np.empty((self.max_steps, 4))
            S = row[i, S_].reshape(4, 4)
            if refine[j]:
                k, H = int(row[i, STEP]) // self.stride, int(row[i, LENGTH])
                H, err = traj.refine(x[i], Us[i, k:H].copy(), Xs[i, k : H + 1].copy(), Ks[i, k:H].copy(), self.goal, S, self.w_u, self.W, self.P_T,
                                     self.Q, R, self.margin * u_max, driven, th, self.plan_dt, self.plan_substeps, self.refine_iterations, traj.ALPHAS,
                                     U_new, X_new, K_new)  # fmt: skip
            else:
                H, err = traj.plan(x[i], PUMPING_GRID, traj.energy(self.goal, th), self.goal, S, self.w_u, self.W, self.P_T, self.Q, R, u_max,
                                   self.margin * u_max, driven, th, self.plan_dt, self.plan_substeps, self.max_steps, self.tail, self.patience, self.iterations,
                                   traj.ALPHAS, U_new, X_new, K_new)  # fmt: skip
            return H, err, U_new, X_new, K_new

        jobs = list(enumerate(zip(members, self.kernel_columns(row, members))))
        results = thread_map(lambda job: one(job[0], *job[1]), jobs)
        for (j, (i, _)), (H, err, U_new, X_new, K_new) in zip(jobs, results):
            row[i, SINCE] = 0.0
            # a refinement starts from the tracked plan's closed-loop rollout and only improves on it: taken when finite
            if H > 0 and (refine[j] or err <= self.accept):
                Us[i, :H], Xs[i, : H + 1], Ks[i, :H] = U_new[:H], X_new[: H + 1], K_new[:H]
                row[i, PHASE], row[i, STEP], row[i, LENGTH] = 1.0, 0.0, H
            elif not refine[j]:
                row[i, PHASE] = 0.0  # no plan reaches upright from here: pump, and try again later
        return plan

    def lqr_catches(self, row: np.ndarray, members: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The ``members`` (indices) whose state ``x`` lies in the region of attraction of their identified model's
        saturated upright LQR, by simulating it for ``catch_time`` (:func:`controllers.trajectory.lqr_catches`)."""
        ok = [traj.lqr_catches(x[i], row[i, K_], self.goal, float(self.u_max[0]), self.driven, th, self.dt, self.substeps,
                               self.catch_steps, self.catch_tol) for i, th in zip(members, self.kernel_columns(row, members))]  # fmt: skip
        return members[np.array(ok, bool)]

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        single = obs.q.ndim == 1
        n = len(np.atleast_2d(obs.q))
        if state is None:
            row, plan, inner = np.zeros((n, ROW_SIZE)), np.zeros((n, self.plan_size)), None
        else:
            row, plan = state
            row = np.array(row, float).reshape(n, ROW_SIZE)
            plan = np.asarray(plan, float).reshape(n, self.plan_size)
            inner = row[:, :STATE_SIZE]
        adaptive, q, v, start = self.observe(obs, inner, episode_start)
        row = np.concatenate([adaptive, row[:, STATE_SIZE:]], axis=1)
        row[start, STATE_SIZE:] = 0.0
        row[start, SINCE] = self.retry_steps  # the first attempt is due at plan_time
        row[:, CLOCK] += 1.0
        row[:, SINCE] += 1.0
        x = np.concatenate([q, v], axis=1)
        dx = state_error(x, self.goal)
        idx = np.arange(n)
        phase, j = row[:, PHASE], row[:, STEP].astype(int)
        k = j // self.stride
        Us, Xs, Ks = self._views(plan)
        tracking = phase == 1.0
        off = tracking & (np.abs(state_error(x, self.reference(Xs, j))[:, :2]).max(axis=1) > self.funnel)
        fresh = ((phase == 0.0) & (row[:, CLOCK] > self.plan_steps) & (row[:, SINCE] >= self.retry_steps)) | off
        fresh |= (phase == 2.0) & (np.abs(dx[:, :2]).max(axis=1) > self.drop)
        # a plan is refined at its knots (every control step where stride is 1)
        refine = tracking & ~off & (row[:, SINCE] >= self.refine_steps) & (row[:, LENGTH] - k > self.tail) & (j % self.stride == 0)
        # inside the upright LQR's region of attraction (simulated on the identified model): balance, no plan needed
        near = (phase != 2.0) & (np.abs(dx[:, :2]).max(axis=1) < self.drop)
        if near.any():
            caught = self.lqr_catches(row, np.flatnonzero(near), x)
            row[caught, PHASE] = 2.0
            fresh[caught] = refine[caught] = False
        due = fresh | refine
        if due.any():
            members = np.flatnonzero(due)
            plan = self.make_plans(row, plan, members, x, refine[members])
            Us, Xs, Ks = self._views(plan)
        phase, j = row[:, PHASE], row[:, STEP].astype(int)
        row[(phase == 1.0) & (j // self.stride >= row[:, LENGTH]), PHASE] = 2.0
        phase = row[:, PHASE]
        j = np.minimum(j, self.max_steps * self.stride - 1)  # the last knot's last control step
        kk = j // self.stride
        u_track = Us[idx, kk] + np.einsum("bi,bi->b", Ks[idx, kk], state_error(x, self.reference(Xs, j)))
        u_lqr = -np.einsum("bi,bi->b", row[:, K_], dx)
        u = np.where(phase == 1.0, u_track, u_lqr)
        pumping = np.flatnonzero(phase == 0.0)
        if len(pumping):
            u[pumping] = self.swing_up(q[pumping], v[pumping], ident.identified_model(row[pumping, THETA], self.model))
        u = np.clip(u, -self.u_max[0], self.u_max[0])
        row[phase == 1.0, STEP] += 1.0
        row[:, MODE] = phase == 2.0
        self.commit(row, u)
        state = (row[0], plan[0]) if single else (row, plan)
        return (u[0, None] if single else u[:, None]), state
