"""What physics allows on the swing-up scenes: the saturation bound beside the LQR's measured catch.

For each swing-up scene of the 2R arm (:func:`applies`) and comparison condition, along each state coordinate about upright
(the others zero): the largest offset the torque limit allows on that condition's plant
(:func:`controllers.region.saturation_bound`, on the plant's own linearization, shrunk by the
input delay), and the largest offset from which the scene's LQR (the balancing part of its
model-based controller, with its nominal gains) brings that plant back
(:func:`controllers.region.axis_catch`, by simulation on the control map). Where the second is far
below the first, a failed catch is the controller's, not physics'. Under observation noise also the
smallest stationary spread of each angle about upright that any controller achieves
(:func:`controllers.region.noise_floor`): no controller holds an angle with a smaller spread, so a
success tolerance of a few such deviations fails often whatever the controller; and the share of the success
rule's windows (both angles within the tolerance for the last 2 s) that the best of a grid of LQG controllers
holds on the linearization (:func:`controllers.region.lqg_hold_share`, an estimate, not a bound), once stationary and
from the most favourable start for those controllers (exactly upright, the estimate exact: for a fixed linear
controller and Gaussian noise the window's states are jointly Gaussian with a covariance that does not depend on the
start, so by Anderson's theorem no start, random or not, holds more of them). A controller whose filter trusted an
accurate estimate at the window's start more than the stationary filter does could hold more (with an exact estimate
and no process noise, every window); how accurate an estimate a swing-up delivers is not computed. A controller that is
not linear can hold more too: beside it, the share the hold of :class:`controllers.PlannedSwingUp` (its law, by
default the driven angle steering the arm's unstable zero dynamics within a reach, :func:`controllers.region.
zero_dynamics_input`, with its rescue, :func:`controllers.region.rescuing`) holds on the same linearization with the
steady Kalman filter and the torque limit, once stationary (:func:`planner_hold_share`), where the planner uses its
hold (:func:`controllers.planned_swingup.hold_pays`; not on the pendubot, whose upright LQR holds every window).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from mbs_envs.controllers.planned_swingup import PlannedSwingUp, hold_window_shares
from mbs_envs.controllers.region import PlantCase, axis_catch, lqg_hold_share, noise_floor, saturation_bound
from mbs_envs.controllers.swingup import SwingUpLQR, upright_linearization
from ..envs.swingup import Q_UP
from .comparison import SCENES, Condition, plant_kwargs
from .evaluation import HOLD

#: the coordinates of the table
AXES = ("q1 [rad]", "q2 [rad]", "v1 [rad/s]", "v2 [rad/s]")


def applies(scene: str) -> bool:
    """Whether the table covers ``scene``: the arm's swing-up scenes (Acrobot, Pendubot). A derived swing-up
    (``mbs_envs.envs.derived_swingup``: the cart-pole) has other coordinates and its own LQR; not covered yet."""
    from ..envs.swingup import SwingUpEnv

    return isinstance(gym.make(SCENES[scene][0]).unwrapped, SwingUpEnv)


def planner_hold_share(
    ctrl: Any, A: np.ndarray, B: np.ndarray, sigma: float, tol: float, windows: int = 2000, seed: int = 0
) -> float:
    """The share of the success rule's windows (both angles within ``tol`` [rad] for 2 s, after 3 s of settling) that
    the hold of ``ctrl`` (a :class:`controllers.PlannedSwingUp`: its law of ``ctrl.hold_law`` on its own nominal
    model, with its rescue or recovery, saturated at its torque limit) holds on the plant linearized as ``(A, B)``,
    observed with noise ``sigma`` on every state entry through the steady Kalman filter
    (:func:`controllers.planned_swingup.hold_window_shares`, the noise drawn from ``seed``)."""
    return float(hold_window_shares(ctrl, A, B, sigma, tol, windows, seed, upright=False)[0])


def catch_rows(scene: str, conditions: list[Condition]) -> list[dict[str, Any]]:
    """One row per condition: ``bound`` and ``lqr_catch`` per coordinate of :data:`AXES` (module docstring)."""
    env_id = SCENES[scene][0]
    nominal = gym.make(env_id).unwrapped
    lqr = SwingUpLQR(nominal)
    u_max, dt, substeps = float(nominal.u_max[0]), float(nominal.dt), int(nominal.substeps)
    x_up = np.concatenate([Q_UP, np.zeros(2)])
    planner = PlannedSwingUp(nominal) if any(cond.obs_noise > 0 for cond in conditions) else None  # its hold's share
    rows = []
    for cond in conditions:
        plant = gym.make(env_id, **plant_kwargs(scene, cond)).unwrapped.model
        A, B = upright_linearization(plant)
        bound = saturation_bound(A, B, u_max, cond.delay * dt)
        case = PlantCase(plant, cond.delay)
        caught = [
            axis_catch(case, x_up, lqr.K, u_max, dt, substeps, j, 1.5 * b if np.isfinite(b) else 5.0)
            for j, b in enumerate(bound)
        ]
        floor = noise_floor(A, B, dt, cond.obs_noise)[:2].tolist() if cond.obs_noise > 0 else None
        hold = start = planner_hold = None
        if cond.obs_noise > 0:
            hold, start = (lqg_hold_share(A, B, dt, cond.obs_noise, nominal.upright_tolerance, int(round(HOLD / dt)), settle_steps=n)
                           for n in (300, 0))  # fmt: skip
            if (
                planner.hold
            ):  # (where the planner uses no hold, none: on the pendubot its upright LQR holds every window)
                planner_hold = planner_hold_share(planner, A, B, cond.obs_noise, nominal.upright_tolerance)
        rows.append({"scene": scene, "condition": cond.name, "bound": [float(b) for b in bound], "lqr_catch": caught, "noise_floor": floor,
                     "lqg_hold": hold, "lqg_hold_from_start": start, "planner_hold": planner_hold})  # fmt: skip
    return rows


def catch_table(rows: list[dict[str, Any]]) -> str:
    """A markdown table of :func:`catch_rows`: ``LQR catch / bound`` per coordinate."""
    lines = ["| scene | condition | " + " | ".join(f"{a}: LQR / bound" for a in AXES) + " | noise floor: std q1 / q2 [rad] | LQG holds | "
             "planner's hold holds |", "|---|---|" + "---|" * (len(AXES) + 3)]  # fmt: skip
    for r in rows:
        cells = [f"{c:.3f} / {b:.3f}" for c, b in zip(r["lqr_catch"], r["bound"])]
        floor = r.get("noise_floor")
        cells.append(f"{floor[0]:.4f} / {floor[1]:.4f}" if floor else "")
        held, start = r.get("lqg_hold"), r.get("lqg_hold_from_start")
        cells.append("" if held is None else f"{held:.0%}" + ("" if start is None else f" ({start:.0%} from upright)"))
        cells.append("" if r.get("planner_hold") is None else f"{r['planner_hold']:.0%}")
        lines.append(f"| {r['scene']} | {r['condition']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
