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
   identified model. Where an angle is more than ``drop`` off upright the member plans again.
3. **Hold** (where it pays, below): where, simulated on the identified model from the current estimate, the hold's
   inner saturated LQR (below) brings the arm to upright with both angles within ``edge`` on the way (its region of
   attraction, sampled as the catch's; within the edge, so that the edge gain, which stops the driven angle, does not
   park a noise-free arm there: entered on the way out of a catch, it held the elbow near 0.09 rad for seconds),
   while the filter's innovations agree with the identified model
   (:meth:`PlannedSwingUp.consistency`: their running normalized square below :data:`NIS_LIMIT`; a member whose
   innovations grow past it goes back to the upright LQR, so torque noise, a lagging or late input or a wrong model
   do not meet a filter that trusts the model) and with both estimated angles within ``hold_back`` of upright, a
   balancing member switches to it, with the filter's process noise lowered to its hold setting (the model is
   trusted near upright). The hold keeps both angles within the success tolerance under observation noise rather
   than catching. **Its law** (``hold_law="zero_dynamics"``, the default; ``hold_law="edge"`` the edge-switched LQRs of docs/physics.md §7): the driven angle steers
   the arm's unstable zero dynamics (:func:`controllers.region.zero_dynamics`, on the identified model's
   linearization: ``p = c . q`` with ``c`` blind to the input obeys ``p'' = a p - g q_j``, its unstable mode ``z =
   p' + sqrt(a) p`` obeys ``z' = sqrt(a) z - g q_j``), asked ``q_j* = reach tanh(k z / reach)`` and followed by a
   critically damped loop (:func:`controllers.region.zero_dynamics_input`; rate 35 /s, reach 0.0975 rad, loop 45
   rad/s: :class:`controllers.region.ZeroDynamicsHold`); **phase 4, rescue**: where ``|z|`` passes 1.35 times what
   the reach can pull back (``g reach / sqrt(a)``) the member asks up to 0.2 rad of the driven angle (the box is
   lost for a while, the arm is not), until ``|z|`` is below 0.7 times it with both angles within ``hold_back``
   (:func:`controllers.region.rescuing`). Why it works: docs/physics.md §7.
   **The edge law** (``hold_law="edge"``): two discrete LQRs of the identified model sampled on the control step
   (input held), switched by :func:`controllers.region.edge_switched`: inside, one that holds the passive angle hard
   (:data:`HOLD_Q`); where the driven angle, ``edge_lead`` seconds ahead at its present rate, is beyond ``edge``, one
   that stops the driven angle at the passive angle's expense (:data:`EDGE_Q`); a holding member whose estimated
   angles leave ``hold_band`` recovers with a third (:data:`RECOVER_Q`) until both are within ``hold_back``
   (:func:`controllers.region.recovering`); its settings are the picks of ``scripts/tune_hold.py`` on the arm's own
   map. **Where it pays** (``hold=None``, the default): the stage is
   used only where, on the nominal model's linearization observed with noise ``obs_noise``, the hold holds at least
   5 points more of such windows than the upright LQR (:func:`hold_pays`): on the acrobot, not on the pendubot
   (the upright LQR holds every window there) nor on the DFKI protocol's scenes.

**Settings.** Picked on tuning seeds (20000-), never on the test seeds, nominal and with the plant's masses and
lengths +-20 %: the prior toward the nominal base parameters (0.1 J^2), the time-varying LQR's input weight (1), the
upright LQR's input weight (10, ``scripts/tune.py --refine-only``) and the guess's patience (5 s). The plan's horizon
(10 s), its iterations (100), the refinement period (0.5 s), its share of the torque limit (85 %), the funnel and the
catch test are design settings. The hold's settings are the picks of ``scripts/tune_zero_dynamics_hold.py`` on the
arm's own map (``controllers.region.ArmMap``); the reasoning and the evidence for the hold are in docs/physics.md §7.
On the DFKI protocol (2-ms control steps) a plan's knots are 0.01 s apart as on our scenes (``plan_step``).

**Memory** (SB3's ``state``): a tuple ``(row, plan)``: ``row`` (n, :data:`ROW_SIZE`) holds the adaptive
controller's memory (identification, filter, last inputs) followed by the phase, the step in the plan, the
plan's length, the steps since the episode started, those since the last plan (or attempt), the hold's three gains
and the filter's consistency; ``plan`` (n, :attr:`plan_size`) the plan's inputs, states and gains. ``plan`` is only replaced (never written in place) when a member plans, so a state
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
from . import region
from . import trajectory as traj
from .swingup import upright_linearization
from .control_map import fast_map, state_error
from .planned_settings import HoldSettings, PlanSettings, split_settings
from .adaptive_swingup import K_, MODE, S_, STATE_SIZE, THETA, XH, AdaptiveSwingUpLQR, unwrapped_env

#: columns after the adaptive controller's: phase (0 pump, 1 track, 2 balance, 3 hold, 4 recover into the hold), step
#: in the plan, plan length, steps since the episode started, steps since the last plan (or attempt), the hold's gains
#: (``hold_law="edge"``: 4 inside, 4 at the edge; ``"zero_dynamics"``: the law's 7 coefficients and a 0 in those 8
#: columns, :data:`ZD_`; then 4 recovering)
PHASE, STEP, LENGTH, CLOCK, SINCE = range(STATE_SIZE, STATE_SIZE + 5)
KH_, KE_, KR_ = (slice(STATE_SIZE + 5 + 4 * i, STATE_SIZE + 9 + 4 * i) for i in range(3))
ZD_ = slice(STATE_SIZE + 5, STATE_SIZE + 12)
#: the filter's consistency while balancing: a running mean of its normalized squared innovations (1 where the
#: observations scatter about the model's predictions as the observation noise alone would)
NIS = STATE_SIZE + 17
ROW_SIZE = STATE_SIZE + 18
#: the plan's terminal weight per unit ``w_T`` (angles [rad^-2], rates [s^2 rad^-2])
TERMINAL = np.diag([1.0, 1.0, 0.1, 0.1])
#: the pumping gains searched for the initial guess (k_q [1/s^2], k_v [1/s], k_E [1/(J s)])
PUMPING_GRID = (
    np.array(np.meshgrid([2.0, 5.0, 10.0, 20.0, 50.0], [0.5, 1.0, 2.0, 5.0, 10.0], [1.0, 2.0, 4.0, 8.0, 16.0]), float)
    .reshape(3, -1)
    .T
)


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


#: the success rule's window [s] (both angles within the tolerance for the last 2 s), over which :func:`hold_pays`
#: counts holds, and the settling before it
HOLD_WINDOW, HOLD_SETTLE = 2.0, 3.0
#: the least gain in held windows [share] for which the hold stage is used
HOLD_GAIN = 0.05
#: the consistency test of the hold: the running mean's time constant [s] and the limit above which the model is not
#: trusted (the member balances, or goes back to balancing)
NIS_TAU, NIS_LIMIT = 0.5, 3.0


def hold_window_shares(ctrl: Any, A: np.ndarray, B: np.ndarray, sigma: float, tol: float, windows: int, seed: int = 0,
                       upright: bool = True) -> np.ndarray:  # fmt: skip
    """The shares of windows of :data:`HOLD_WINDOW` seconds, after :data:`HOLD_SETTLE` seconds of settling, in which
    both angles stay within ``tol`` [rad]: on the plant linearized about upright as ``(A, B)`` (continuous), discretized
    on ``ctrl``'s control step and observed with noise ``sigma`` on every entry through its steady Kalman filter, under
    the upright LQR of ``ctrl`` (a :class:`PlannedSwingUp`; where ``upright``) and its hold (its law,
    ``ctrl.hold_law``, on its nominal model, with its phase 4: the zero-dynamics law's rescue, or the edge law's
    recovery gain outside the band until within ``hold_back``), both saturated at its torque limit, on the same noise
    (:func:`controllers.region.hold_shares`, drawn from ``seed``). Shape ``(2,)``, or ``(1,)`` (the hold's alone)."""
    A_n, B_n = upright_linearization(ctrl.model)
    with region.quiet_riccati():
        A_d, B_d = region.discretize(A, B, ctrl.dt)
        L = region.steady_kalman(A_d, sigma)[0]
    terms = ctrl.hold_gains_of(A_n[None], B_n[None])[0]
    zd_law = ctrl.hold_law == "zero_dynamics"
    K_hold, K_edge, K_rec = terms[12:], terms[12:] if zd_law else terms[4:8], terms[8:12]  # (the inside gain: last)
    K_up = np.asarray(ctrl.K, float).reshape(4)
    K, K_e, K_r = (np.stack([K_up, k]) if upright else k[None] for k in (K_hold, K_edge, K_rec))
    coef = None if not zd_law else np.stack([np.full(7, np.nan), terms[:7]]) if upright else terms[None, :7]
    edge, lead, band, back = ctrl.edge, ctrl.edge_lead, ctrl.hold_band, ctrl.hold_back
    if upright:  # the upright LQR first: no edge, no band
        edge, lead, band, back = ([none, h] for none, h in zip((np.inf, 0.0, np.inf, np.inf), (edge, lead, band, back)))
    return region.hold_shares(A_d, B_d, L, K, sigma, tol, int(round(HOLD_WINDOW / ctrl.dt)), windows, int(round(HOLD_SETTLE / ctrl.dt)),
                              seed, float(ctrl.u_max[0]), K_e=K_e, edge=edge, lead=lead, joint=ctrl.driven, K_r=K_r, band=band, back=back,
                              coef=coef, zd=ctrl.zd)  # fmt: skip


def hold_pays(ctrl: Any, tol: float, windows: int = 1000, seed: int = 0) -> bool:
    """Whether the hold stage of ``ctrl`` (a :class:`PlannedSwingUp`) pays on its nominal model: observed with noise
    ``ctrl.obs_noise`` on every entry, the hold keeps both angles within ``tol`` [rad] for :data:`HOLD_WINDOW` seconds in
    at least :data:`HOLD_GAIN` more of ``windows`` windows than the upright LQR (:func:`hold_window_shares` on the
    nominal model's linearization, the same noise for both). False without observation noise (``obs_noise = 0``: no
    filter)."""
    if ctrl.obs_noise <= 0:
        return False
    A, B = upright_linearization(ctrl.model)
    shares = hold_window_shares(ctrl, A, B, ctrl.obs_noise, tol, windows, seed)
    return bool(shares[1] >= shares[0] + HOLD_GAIN)


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
    plan : PlanSettings, optional
        The plan and the catch (:class:`controllers.planned_settings.PlanSettings`; default its defaults).
    hold : HoldSettings or bool, optional
        The hold stage (:class:`controllers.planned_settings.HoldSettings`); a bool or None: the default settings
        with ``enabled`` so (None: the hold is used where it pays, :func:`hold_pays`).
    **settings
        Any field of :class:`~controllers.planned_settings.PlanSettings` or :class:`~controllers.planned_settings.HoldSettings`
        by name (``plan_time=0.0``, ``hold_law="edge"``, ...), applied on top of ``plan`` and ``hold``: the keys of
        the tuned entries; an unknown name is a ``ValueError``. The control step's limits (the plan's grid in control
        steps, ``hold_omega <= pi / dt``, ``hold_reach <= hold_rescue_reach <= drop``) are checked here.
    """

    tuned_name = "identified iLQR + TVLQR"

    def __init__(self, env: Any, k_q: Any = None, k_v: Any = None, k_E: Any = None, catch: Any = None, release: float = 4.0,
                 lqr_r: Any = None, window: int = 10, prior: float = 0.1, obs_noise: float = 0.01,
                 process_noise: Any = ((1e-4, 1e-2), (3e-4, 3e-2)), gate: Any = None, plan: PlanSettings | None = None,
                 hold: HoldSettings | bool | None = None, **settings: Any):  # fmt: skip
        plan, hold = split_settings(plan, hold, settings)  # every setting validated before anything is built
        # a catch level only for the inherited switching rule, which this controller does not use (module docstring)
        catch = 1.0 if catch is None else catch
        super().__init__(env, k_q=k_q, k_v=k_v, k_E=k_E, catch=catch, release=release, lqr_r=lqr_r, window=window, prior=prior, obs_noise=obs_noise,
                         process_noise=process_noise, gate=gate)  # fmt: skip
        self.plan_settings, self.hold_settings = plan, hold

        def steps(t: float, step: float = self.dt) -> int:  # a duration [s] in steps of ``step``
            return int(round(t / step))

        # the plan's grid: ``stride`` control steps per knot, its model stepped by RK4 in steps of at most ``plan_h``
        self.stride = max(1, steps(plan.plan_step))
        self.plan_dt = self.stride * self.dt
        self.plan_substeps = (
            self.substeps if self.stride == 1 else max(1, int(np.ceil(round(self.plan_dt / plan.plan_h, 9))))
        )
        self.plan_steps = steps(plan.plan_time)
        self.max_steps = max(2, steps(plan.horizon, step=self.plan_dt))
        self.tail = min(steps(plan.tail, step=self.plan_dt), self.max_steps - 1)
        self.patience = max(1, steps(plan.patience, step=self.plan_dt))
        self.retry_steps = max(1, steps(plan.retry))
        self.refine_steps = max(1, steps(plan.refine_every))
        self.iterations, self.refine_iterations = plan.iterations, plan.refine_iterations
        self.w_u, self.w_T = plan.w_u, plan.w_T
        self.P_T = self.w_T * TERMINAL
        self.W = plan.w_x * TERMINAL
        self.track_r = plan.track_r
        self.catch_steps = max(10, steps(plan.catch_time))
        self.catch_tol, self.margin, self.accept, self.funnel, self.drop = (plan.catch_tol, plan.margin, plan.accept,
                                                                            plan.funnel, plan.drop)  # fmt: skip
        self.goal = np.concatenate([Q_UP, np.zeros(2)])
        self.Q_hold, self.Q_edge, self.Q_recover = (self.hold_weights(w, name) for w, name in ((hold.hold_q, "hold_q"), (hold.edge_q, "edge_q"),
                                                                                          (hold.recover_q, "recover_q")))  # fmt: skip
        self.R_hold = np.full((1, 1), hold.hold_r)
        self.edge, self.edge_lead, self.hold_band, self.hold_back = (
            hold.edge,
            hold.edge_lead,
            hold.hold_band,
            hold.hold_back,
        )
        self.hold_law = hold.hold_law
        omega = check.real(hold.hold_omega, "hold_omega", 0.0, np.pi / self.dt, low_open=True)
        rescue = check.real(hold.hold_rescue_reach, "hold_rescue_reach", hold.hold_reach, self.drop)
        self.zd = region.ZeroDynamicsHold(
            hold.hold_rate, hold.hold_reach, omega, rescue, hold.hold_trigger, hold.hold_release
        )
        self.Q_w_hold = np.diag(np.repeat(np.array(hold.hold_noise), 2) ** 2)
        self.hold = (
            hold_pays(self, getattr(unwrapped_env(env), "upright_tolerance", 0.1))
            if hold.enabled is None
            else hold.enabled
        )
        if self.hold and self.obs_noise <= 0:
            raise ValueError(
                "hold=True needs the filter (obs_noise > 0): its consistency test measures innovations in units of obs_noise"
            )
        H = self.max_steps
        self.plan_size = H + 4 * (H + 1) + 4 * H

    def _views(self, plan: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(U (n, H), X (n, H + 1, 4), K (n, H, 4))`` views of the plan rows."""
        n, H = len(plan), self.max_steps
        return (
            plan[:, :H],
            plan[:, H : H + 4 * (H + 1)].reshape(n, H + 1, 4),
            plan[:, H + 4 * (H + 1) :].reshape(n, H, 4),
        )

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

    def make_plans(
        self, row: np.ndarray, plan: np.ndarray, members: np.ndarray, x: np.ndarray, refine: np.ndarray
    ) -> np.ndarray:
        """Plan for ``members`` from ``x`` (n, 4) on their identified models: afresh, or where ``refine`` (per
        member listed) from the rest of the plan being tracked. Writes ``row`` (phase, step, length, since) in
        place and returns a new plan array (the one passed in untouched). Members plan on :func:`plan_threads`
        threads at once (the compiled planner releases the GIL; each member's plan is its own, so the result does
        not depend on how many)."""
        plan = plan.copy()
        Us, Xs, Ks = self._views(plan)
        u_max, driven, R = float(self.u_max[0]), self.driven, self.track_r

        def one(j: int, i: int, th: np.ndarray) -> tuple:
            U_new, X_new, K_new = (
                np.empty(self.max_steps),
                np.empty((self.max_steps + 1, 4)),
                np.empty((self.max_steps, 4)),
            )
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

    def lqr_catches(
        self, row: np.ndarray, members: np.ndarray, x: np.ndarray, K: np.ndarray | None = None, bound: float = np.inf
    ) -> np.ndarray:
        """The ``members`` (indices) whose state ``x`` lies in the region of attraction of their identified model's
        saturated upright LQR (or of the gains ``K``, one row per member listed), by simulating it for ``catch_time``
        with the angles within ``bound`` of upright on the way (:func:`controllers.trajectory.lqr_catches`)."""
        K = row[members, K_] if K is None else K
        ok = [traj.lqr_catches(x[i], np.ascontiguousarray(k), self.goal, float(self.u_max[0]), self.driven, th, self.dt, self.substeps,
                               self.catch_steps, self.catch_tol, bound) for i, k, th in zip(members, K, self.kernel_columns(row, members))]  # fmt: skip
        return members[np.array(ok, bool)]

    def hold_weights(self, w: Any, name: str) -> np.ndarray:
        """``Q = diag`` of the weights ``(passive angle, driven angle, rates)`` (positive), validated."""
        w = check.reals(w, name)
        if w.shape != (3,) or not (np.isfinite(w).all() and (w > 0).all()):
            raise ValueError(
                f"{name} must be three positive weights (passive angle, driven angle, rates), got {w.tolist()!r}"
            )
        passive = 1 - self.driven
        return np.diag([w[0] if j == passive else w[1] for j in range(2)] + [w[2], w[2]])

    def hold_gains_of(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """The hold's terms for each linearization ``(A, B)`` (shapes (m, 4, 4), (m, 4, 1)), shape ``(m, 16)``: the
        12 its memory keeps (``hold_law="edge"``: the inside and the edge gains; ``"zero_dynamics"``:
        :func:`controllers.region.zero_dynamics`' 7 coefficients and a 0; then the recovery gain), then the inside
        gain, whose simulated region decides the entry into the hold (:meth:`update_hold`). The gains are the discrete
        LQRs of ``sum x^T Q x + R u^2`` on the control step (input held; ``Q`` the hold's, the edge's, the
        recovery's, ``R`` the hold's); NaN where a Riccati equation has no stabilizing solution (or, for the zero
        dynamics, where the arm has no unstable one). Discrete, not the continuous LQR sampled: the hold's weights
        ask for gains the sampled continuous design does not stabilize."""
        out = np.full((len(A), 16), np.nan)
        with region.quiet_riccati():
            for i, (A_i, B_i) in enumerate(zip(A, B)):
                A_d, B_d = region.discretize(A_i, B_i, self.dt)
                try:
                    K = [
                        region.dlqr(A_d, B_d, Q, float(self.R_hold[0, 0]))[0]
                        for Q in (self.Q_hold, self.Q_edge, self.Q_recover)
                    ]
                except (np.linalg.LinAlgError, ValueError):
                    continue
                stable = all(np.abs(np.linalg.eigvals(A_d - B_d @ k[None])).max() < 1.0 for k in K)
                if stable and np.isfinite(K).all():
                    inside = (
                        np.concatenate([region.zero_dynamics(A_i, B_i, self.driven), [0.0]])
                        if self.hold_law == "zero_dynamics"
                        else np.concatenate(K[:2])
                    )
                    out[i] = np.concatenate([inside, K[2], K[0]])
        return out

    def hold_gains(self, row: np.ndarray, members: np.ndarray) -> np.ndarray:
        """The hold's terms of each of ``members`` on its identified model (:meth:`hold_gains_of`), shape
        ``(len(members), 16)``."""
        A, B = upright_linearization(ident.identified_model(row[members, THETA], self.model), (len(members),))
        return self.hold_gains_of(A, B)

    def filter_noise(self, state: np.ndarray) -> np.ndarray:
        """As :meth:`AdaptiveSwingUpLQR.filter_noise`, with the hold setting where the member holds (``MODE`` 2)."""
        return np.where((state[:, MODE] > 1.5)[:, None, None], self.Q_w_hold, super().filter_noise(state))

    def consistency(
        self, row: np.ndarray, y: np.ndarray, inner: np.ndarray, members: np.ndarray, phase: np.ndarray
    ) -> None:
        """The running mean (time constant :data:`NIS_TAU`) of ``|y - x^-|^2 / (4 obs_noise^2)`` of ``members``, in place
        in ``row[:, NIS]``: ``x^-`` the identified model's one-step prediction from the last estimate under the input
        applied (``inner``: the memory before this step), ``y`` the observation; 1 on average where the observations
        scatter about the predictions by the observation noise alone (the filter's own uncertainty adds a little), far
        above it where the plant does what the model does not (torque noise, a lagging or late input, a wrong model).
        A member that was not balancing starts at twice :data:`NIS_LIMIT` (about 0.45 s of consistent steps to reach it)."""
        model = ident.identified_model(inner[members, THETA], self.model)
        x_pred = fast_map(model, inner[members, XH], self.applied(inner[members])[:, None], self.dt, self.substeps)
        z = np.sum(state_error(y[members], x_pred) ** 2, axis=1) / (4.0 * self.obs_noise**2)
        mean = np.where(phase[members] >= 2.0, row[members, NIS], 2.0 * NIS_LIMIT)
        row[members, NIS] = mean + min(1.0, self.dt / NIS_TAU) * (z - mean)

    def update_hold(self, row: np.ndarray, x: np.ndarray, y: np.ndarray, inner: np.ndarray | None, phase: np.ndarray, fresh: np.ndarray,
                    theta_before: np.ndarray | None) -> None:  # fmt: skip
        """Phases 3 and 4 (module docstring), in place on ``row``: members balancing since before this step (``phase``
        2, not planning afresh) switch to the hold LQR where its simulated region says and the filter is consistent
        (:meth:`consistency` below :data:`NIS_LIMIT`); a holding or recovering member goes back to balancing where it
        is not, a holding one recovers outside ``hold_band`` and a recovering one holds again within ``hold_back``
        (:func:`controllers.region.recovering`'s rule); the gains are solved again where the identified model changed
        this step (back to balancing where it has none)."""
        if inner is None:
            return
        balancing = np.flatnonzero((phase >= 2.0) & ~fresh)
        if len(balancing):
            self.consistency(row, y, inner, balancing, phase)
        trusted = row[:, NIS] < NIS_LIMIT
        off = np.abs(state_error(x, self.goal)[:, :2]).max(axis=1)
        holding, recovering = ((phase == p) & ~fresh for p in (3.0, 4.0))
        row[(holding | recovering) & ~trusted, PHASE] = 2.0
        if self.hold_law == "zero_dynamics":
            dx = state_error(x, self.goal)
            rescue = region.rescuing(dx, row[:, ZD_], recovering, self.zd, self.hold_back)
            row[(holding | recovering) & trusted, PHASE] = np.where(rescue, 4.0, 3.0)[(holding | recovering) & trusted]
        else:
            row[holding & trusted & (off > self.hold_band), PHASE] = 4.0
            row[recovering & trusted & (off <= self.hold_back), PHASE] = 3.0
        candidates = np.flatnonzero((phase == 2.0) & ~fresh & trusted & (off <= self.hold_back))
        if len(candidates):
            K = self.hold_gains(row, candidates)
            ok = np.isfinite(K).all(axis=1)
            held = self.lqr_catches(
                row, candidates[ok], x, K[ok, 12:], self.edge
            )  # within the edge on the way: not parked at it
            row[held, KH_.start : KR_.stop] = K[ok][np.isin(candidates[ok], held), :12]
            row[held, PHASE] = 3.0
        if theta_before is not None:
            changed = np.flatnonzero(
                (row[:, PHASE] >= 3.0) & (phase >= 3.0) & ~fresh & (row[:, THETA] != theta_before).any(axis=1)
            )
            if len(changed):
                K = self.hold_gains(row, changed)
                ok = np.isfinite(K).all(axis=1)
                row[changed[ok], KH_.start : KR_.stop] = K[ok, :12]
                row[changed[~ok], PHASE] = 2.0

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        single = obs.q.ndim == 1
        n = len(np.atleast_2d(obs.q))
        if state is None:
            row, plan, inner = np.zeros((n, ROW_SIZE)), np.zeros((n, self.plan_size)), None
        else:
            if not (isinstance(state, tuple) and len(state) == 2):
                raise ValueError(
                    f"state must be the (row, plan) pair this controller returned, got {type(state).__name__}"
                )
            row, plan = state
            row = check.shaped(row, "state's row", (n, ROW_SIZE))
            plan = check.shaped(plan, "state's plan", (n, self.plan_size))
            inner = row[:, :STATE_SIZE]
        theta_before = None if inner is None else inner[:, THETA].copy()
        y = np.concatenate([np.atleast_2d(obs.q), np.atleast_2d(obs.v)], axis=1)
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
        phase_before = phase.copy()  # (``phase`` is a view of ``row``)
        k = j // self.stride
        Us, Xs, Ks = self._views(plan)
        tracking = phase == 1.0
        off = tracking & (np.abs(state_error(x, self.reference(Xs, j))[:, :2]).max(axis=1) > self.funnel)
        fresh = ((phase == 0.0) & (row[:, CLOCK] > self.plan_steps) & (row[:, SINCE] >= self.retry_steps)) | off
        fresh |= (phase >= 2.0) & (np.abs(dx[:, :2]).max(axis=1) > self.drop)
        # a plan is refined at its knots (every control step where stride is 1)
        refine = (
            tracking
            & ~off
            & (row[:, SINCE] >= self.refine_steps)
            & (row[:, LENGTH] - k > self.tail)
            & (j % self.stride == 0)
        )
        # inside the upright LQR's region of attraction (simulated on the identified model): balance, no plan needed
        near = (phase < 2.0) & (np.abs(dx[:, :2]).max(axis=1) < self.drop)
        if near.any():
            caught = self.lqr_catches(row, np.flatnonzero(near), x)
            row[caught, PHASE] = 2.0
            fresh[caught] = refine[caught] = False
        if self.hold:
            self.update_hold(row, x, y, inner, phase_before, fresh, theta_before)
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
        holding = (phase == 3.0)[:, None]
        if self.hold_law == "zero_dynamics":  # (balancing: the upright LQR)
            K_in, K_e, coef = (
                row[:, K_],
                row[:, K_],
                np.where((phase >= 3.0)[:, None], row[:, ZD_], np.nan),
            )  # (phase 4: rescuing)
        else:  # (balancing: the upright LQR, no edge)
            K_in = np.where(holding, row[:, KH_], row[:, K_])
            K_e, coef = np.where(holding, row[:, KE_], K_in), None
        u_lqr = region.hold_input(
            dx, phase == 4.0, K_in, K_e, row[:, KR_], self.edge, self.edge_lead, self.driven, coef, self.zd
        )
        u = np.where(phase == 1.0, u_track, u_lqr)
        pumping = np.flatnonzero(phase == 0.0)
        if len(pumping):
            u[pumping] = self.swing_up(q[pumping], v[pumping], ident.identified_model(row[pumping, THETA], self.model))
        u = np.clip(u, -self.u_max[0], self.u_max[0])
        row[phase == 1.0, STEP] += 1.0
        row[:, MODE] = np.where(phase >= 3.0, 2.0, phase == 2.0)
        self.commit(row, u)
        state = (row[0], plan[0]) if single else (row, plan)
        return (u[0, None] if single else u[:, None]), state
