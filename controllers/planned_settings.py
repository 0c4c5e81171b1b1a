"""The settings of :class:`~mbs_envs.controllers.planned_swingup.PlannedSwingUp`, grouped and validated in one place.

:class:`PlanSettings` holds the swing-up's plan (its grid, its iLQR, when it is taken, tracked, refined and dropped,
and the catch by the upright LQR); :class:`HoldSettings` the hold stage that follows a catch. Each is a frozen
dataclass whose construction validates every field (a ``ValueError`` naming the field); what depends on the env's
control step (the step counts, the hold's loop frequency) is checked where the controller is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from mbs_envs import validation as check

#: the hold's laws (:class:`HoldSettings` ``hold_law``)
HOLD_LAWS = ("zero_dynamics", "edge")
#: the hold's weights (passive angle, driven angle, rates) inside, at the edge and recovering (``scripts/tune_hold.py``)
HOLD_Q, EDGE_Q, RECOVER_Q = (3e4, 5.0, 0.2), (0.006, 3.0, 100.0), (0.2, 400.0, 10.0)


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


def three_weights(w: Any, name: str) -> tuple[float, float, float]:
    """``(passive angle, driven angle, rates)`` weights, three positive finite numbers, or a ``ValueError``."""
    x = check.reals(w, name)
    if x.shape != (3,) or not (np.isfinite(x).all() and (x > 0).all()):
        raise ValueError(
            f"{name} must be three positive weights (passive angle, driven angle, rates), got {x.tolist()!r}"
        )
    return tuple(float(v) for v in x)


@dataclasses.dataclass(frozen=True)
class PlanSettings:
    """The plan of a swing-up and the catch that ends it.

    Attributes
    ----------
    plan_time : float
        [s] of pumping before the first attempt to plan.
    horizon : float
        The longest plan [s].
    tail : float
        Seconds the plan continues after the pumping guess's closest approach to upright.
    iterations, refine_iterations : int
        iLQR iterations of a new plan and of a plan refined from where the arm is.
    w_u, w_T, w_x : float
        The plan's effort weight [1/(N m)^2 s], and the scales of its terminal and running state weights
        (``TERMINAL`` times each; :func:`mbs_envs.controllers.trajectory.ilqr`'s objective). ``w_x = 0``: a running
        cost quadratic in wrapped angles far from upright made plans worse.
    margin : float
        The share of the torque limit the plan may use (the rest is the feedback's), in ``(0, 1]``.
    accept : float
        A plan is taken when it ends within this distance of upright (largest wrapped entry [rad, rad/s]).
    retry, refine_every : float
        Seconds between attempts to plan while pumping, and between refinements of the plan being tracked.
    funnel : float
        Largest angle off the plan [rad] before the member plans afresh.
    drop : float
        Largest angle off upright [rad] before a balancing member plans afresh.
    patience : float
        [s]: the initial guess trades a closer approach to upright against an earlier one, ``e`` times the
        cost-to-go for ``patience`` seconds sooner (:func:`mbs_envs.controllers.trajectory.pumping_search`).
    track_r : float
        The time-varying LQR's input weight [(N m)^-2] (its state weight is the upright LQR's ``Q``).
    catch_time, catch_tol : float
        A member not balancing is handed to the upright LQR where, simulated on the identified model from the
        current state for ``catch_time`` [s], the saturated LQR ends within ``catch_tol`` of upright (rad, rad/s;
        checked only within ``drop`` of upright).
    plan_step, plan_h : float
        The plan's time grid [s]: its knots ``stride = max(1, round(plan_step / dt))`` control steps apart (inputs
        held, gains and states per knot), its model stepped by RK4 in ``ceil(stride dt / plan_h)`` sub-steps (where
        ``stride`` is 1, the env's own sub-steps).
    """

    plan_time: float = 3.0
    horizon: float = 10.0
    tail: float = 0.5
    iterations: int = 100
    refine_iterations: int = 10
    w_u: float = 0.1
    w_T: float = 1e4
    w_x: float = 0.0
    margin: float = 0.85
    accept: float = 0.05
    retry: float = 1.0
    refine_every: float = 0.5
    funnel: float = 0.5
    drop: float = 0.3
    patience: float = 5.0
    track_r: float = 1.0
    catch_time: float = 3.0
    catch_tol: float = 0.01
    plan_step: float = 0.01
    plan_h: float = 0.005

    def __post_init__(self):
        for name in ("plan_time", "tail", "patience", "catch_time"):
            _set(self, name, check.real(getattr(self, name), name, 0.0, 1e4))
        for name in ("horizon", "retry", "refine_every", "plan_step"):
            _set(self, name, check.real(getattr(self, name), name, 0.0, 1e4, low_open=True))
        for name in ("iterations", "refine_iterations"):
            _set(self, name, check.integer(getattr(self, name), name, 0, 10**6))
        for name in ("w_u", "w_T", "track_r", "catch_tol", "accept", "funnel", "drop"):
            _set(self, name, check.positive(getattr(self, name), name))
        _set(self, "w_x", check.nonnegative(self.w_x, "w_x"))
        _set(self, "margin", check.real(self.margin, "margin", 0.0, 1.0, low_open=True))
        _set(self, "plan_h", check.real(self.plan_h, "plan_h", 0.0, 1.0, low_open=True))


@dataclasses.dataclass(frozen=True)
class HoldSettings:
    """The hold stage after a catch (``PlannedSwingUp``'s phase 3).

    Attributes
    ----------
    enabled : bool, optional
        Whether a balancing member switches to the hold; None (default): where it pays (``hold_pays``).
    hold_law : str
        The hold's law (:data:`HOLD_LAWS`): ``"zero_dynamics"`` (default): the driven angle steers the arm's
        unstable zero dynamics (``hold_rate``, ``hold_reach``, ``hold_omega``), rescuing the arm past what its reach
        can pull back (``hold_rescue_reach``, ``hold_trigger``, ``hold_release``); ``"edge"``: the two LQRs of
        ``hold_q`` and ``edge_q`` switched at ``edge``, with the band and the recovery gain.
    hold_q, edge_q, recover_q : tuple of three floats
        The hold's inside, edge and recovery gains' state weights: the passive angle's, the driven angle's and the
        rates' (``Q = diag``) of their discrete LQRs.
    hold_r : float
        The input weight [(N m)^-2] of the hold's discrete LQRs.
    edge, edge_lead : float
        The hold switches to its edge gain where the driven angle ``edge_lead`` [s] ahead at its present rate is more
        than ``edge`` [rad] off upright.
    hold_band, hold_back : float
        [rad]: a holding member recovers where an estimated angle is more than ``hold_band`` off upright, until both
        are within ``hold_back`` again; a balancing member switches to the hold only within ``hold_back``
        (``0 < hold_back <= hold_band``).
    hold_rate : float
        [1/s]: the zero dynamics' unstable mode's closed-loop decay rate where the driven angle's request is linear.
    hold_reach : float
        [rad]: the most the driven angle is asked off upright, in ``(0, hold_band]``.
    hold_omega : float
        [rad/s]: the driven angle's loop (critically damped); at most ``pi / dt``.
    hold_rescue_reach, hold_trigger, hold_release : float
        The zero-dynamics hold's rescue: with the reach ``hold_rescue_reach`` [rad] (from ``hold_reach`` to the plan's
        ``drop``), where the unstable mode exceeds ``hold_trigger`` times what the reach can pull back, until it is
        below ``hold_release`` times that (``0 < hold_release < hold_trigger``).
    hold_noise : (float, float)
        The filter's per-step process-noise standard deviations (angle [rad], rate [rad/s]) while holding.
    """

    enabled: bool | None = None
    hold_law: str = "zero_dynamics"
    hold_q: Any = HOLD_Q
    edge_q: Any = EDGE_Q
    recover_q: Any = RECOVER_Q
    hold_r: float = 1e-3
    edge: float = 0.083
    edge_lead: float = 0.025
    hold_band: float = 0.1
    hold_back: float = 0.085
    hold_rate: float = 35.0
    hold_reach: float = 0.0975
    hold_omega: float = 45.0
    hold_rescue_reach: float = 0.2
    hold_trigger: float = 1.35
    hold_release: float = 0.7
    hold_noise: Any = (1e-5, 1e-4)

    def __post_init__(self):
        if self.enabled is not None:
            _set(self, "enabled", check.boolean(self.enabled, "hold"))
        for name in ("hold_q", "edge_q", "recover_q"):
            _set(self, name, three_weights(getattr(self, name), name))
        for name in ("hold_r", "edge", "hold_band", "hold_rate", "hold_omega", "hold_rescue_reach"):
            _set(self, name, check.positive(getattr(self, name), name))
        _set(self, "edge_lead", check.nonnegative(self.edge_lead, "edge_lead"))
        if self.hold_law not in HOLD_LAWS:
            raise ValueError(f"hold_law must be one of {HOLD_LAWS}, got {self.hold_law!r}")
        _set(self, "hold_reach", check.real(self.hold_reach, "hold_reach", 0.0, self.hold_band, low_open=True))
        _set(self, "hold_release", check.real(self.hold_release, "hold_release", 0.0, 1.0, low_open=True))
        _set(self, "hold_trigger", check.real(self.hold_trigger, "hold_trigger", self.hold_release, 1e3, low_open=True))
        _set(self, "hold_back", check.real(self.hold_back, "hold_back", 0.0, self.hold_band, low_open=True))
        sigma = check.reals(self.hold_noise, "hold_noise")
        if sigma.shape != (2,) or not (np.isfinite(sigma).all() and (sigma > 0).all()):
            raise ValueError(f"hold_noise must be (angle, rate) standard deviations, positive, got {self.hold_noise!r}")
        _set(self, "hold_noise", (float(sigma[0]), float(sigma[1])))


def split_settings(plan: PlanSettings | None, hold: HoldSettings | bool | None, flat: dict) -> tuple:
    """``(PlanSettings, HoldSettings)`` from the objects given (None: the defaults; ``hold`` a bool or None: the
    defaults with that ``enabled``) with the flat keyword arguments ``flat`` applied, each to the one that has the
    field; an unknown name is a ``ValueError`` naming it."""
    if not isinstance(hold, HoldSettings):
        hold = HoldSettings(enabled=hold)
    plan = PlanSettings() if plan is None else plan
    if not isinstance(plan, PlanSettings):
        raise ValueError(f"plan must be a PlanSettings, got {type(plan).__name__}")
    plan_fields = {f.name for f in dataclasses.fields(PlanSettings)}
    hold_fields = {f.name for f in dataclasses.fields(HoldSettings)} - {"enabled"}
    unknown = sorted(set(flat) - plan_fields - hold_fields)
    if unknown:
        raise ValueError(f"unknown setting(s) {unknown} of PlannedSwingUp (PlanSettings, HoldSettings)")
    plan = dataclasses.replace(plan, **{k: v for k, v in flat.items() if k in plan_fields})
    hold = dataclasses.replace(hold, **{k: v for k, v in flat.items() if k in hold_fields})
    return plan, hold
