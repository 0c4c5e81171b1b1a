"""Scene: a double pendulum on a cart, written as a user writes a mechanism: its Lagrangian, derived.

A cart (mass ``m0``, position ``x`` on a horizontal rail, driven by a force) carries a double pendulum of two uniform rods: the
first at angle ``th1`` from upright (driven at the pivot), the second at ``th2`` relative to the first (driven at
the elbow); gravity along -y. ``q = (x, th1, th2)``, every coordinate driven. The task tracks a random smooth
reference about the upright posture, where gravity pulls every link away: computed torque's model of the whole
chain against PD's springs.
The user code (as docs/tutorial_lagrangian.md writes it) is everything above the registry hooks: 27 lines with
its imports, blank lines not counted.
"""

import sympy as sp

from ..models import symbolic
from ..models.symbolic import dynamicsymbols
from .derived import DerivedTrackingEnv

t = symbolic.time_symbol()
x, th1, th2 = dynamicsymbols("x th1 th2")
m0, m1, m2, l1, l2, g = sp.symbols("m0 m1 m2 l1 l2 g")
up = lambda a: sp.Matrix([sp.sin(a), sp.cos(a)])  # noqa: E731  (a unit vector at angle a from upright)
pivot, elbow = sp.Matrix([x, 0]), sp.Matrix([x, 0]) + l1 * up(th1)
c1, c2 = pivot + l1 / 2 * up(th1), elbow + l2 / 2 * up(th1 + th2)  # the rods' centres of mass
speed2 = lambda p: p.diff(t).dot(p.diff(t))  # noqa: E731
T = (m0 * x.diff(t) ** 2 + m1 * speed2(c1) + m1 * l1**2 / 12 * th1.diff(t) ** 2
     + m2 * speed2(c2) + m2 * l2**2 / 12 * (th1.diff(t) + th2.diff(t)) ** 2) / 2  # fmt: skip
V = g * (m1 * c1[1] + m2 * c2[1])
params = {"m0": (1.0, "positive"), "m1": (0.5, "positive"), "m2": (0.3, "positive"), "l1": (0.6, "positive"),
          "l2": (0.5, "positive"), "g": 9.81, "b_x": (0.5, "nonnegative"), "b_1": (0.01, "nonnegative"),
          "b_2": (0.01, "nonnegative")}  # fmt: skip
#: the derived model's class (derived and compiled once, then read from the disk cache)
CartDoublePendulum = type(symbolic.derive("CartDoublePendulum", [x, th1, th2], T, V, params,
                                          damping={x: "b_x", th1: "b_1", th2: "b_2"}))  # fmt: skip


class CartDoublePendulumEnv(DerivedTrackingEnv):
    """Double pendulum on a cart, every coordinate driven, derived from its Lagrangian: track a reference about upright.

    ## Description

    A cart (mass ``m0``, position ``x`` on a horizontal rail, driven by a force) carries a double pendulum of two
    uniform rods: the first at ``th1`` from upright (driven at the pivot), the second at ``th2`` relative to the
    first (driven at the elbow); gravity along -y. The equations are derived by
    :func:`mbs_envs.models.symbolic.derive` from the energies written in the module. The task tracks a random
    smooth reference about the upright posture, where gravity pulls every link away: computed torque's model of
    the whole chain against PD's springs.

    ## Action Space

    ``Box(-1, 1, (3,), float32)``: the cart force and the two joint torques over ``torque_limit`` (40 N, 10 N m, 3 N m).
    Finite out-of-range actions saturate; NaN/inf or wrongly shaped actions raise ``ValueError``.

    ## Observation Space

    ``Box((18,), float32)``: ``[cos q (3), sin q (3), v (3), e (3), v_ref (3), a_ref (3)]`` with
    ``q = (x, th1, th2)``, the tracking error ``e = wrap(q_ref - q)`` of the tracked coordinates (all three) and its
    reference's rate and acceleration (:func:`mbs_envs.envs.tracking.decode_tracking`).

    ## Rewards

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2)`` over the tracked coordinates, default weights
    ``(1, 0.1, 0.001)``; the terms are in ``info`` (``reward_tracking``, ``reward_velocity``, ``reward_effort``).

    ## Starting State

    Reference centres ``U(-0.5, 0.5)`` m for the cart and ``U(-0.3, 0.3)`` rad for the angles, total amplitudes
    at most 0.3; the start is the reference's state plus ``U(-0.1, 0.1)``.

    ## Episode End

    Truncation after ``max_episode_steps`` (500, 5 s at ``dt = 0.01``); termination only on divergence
    (``info["diverged"]``).

    ## Arguments

    ``gym.make("mbs_envs/CartDoublePendulum-v0", params=None, torque_limit=(40.0, 10.0, 3.0), dt=0.01, integrator="rk4", substeps=..., compiled=True,
    render_mode=None)``; ``params`` overrides the derived model's parameters (``m0, m1, m2, l1, l2, g, b_x, b_1, b_2``).

    ## Version History

    - v0: initial version.
    """

    step_kernel = DerivedTrackingEnv.step_kernel  # the same task: its compiled step

    def __init__(self, params=None, torque_limit=(40.0, 10.0, 3.0), **kwargs):
        super().__init__(CartDoublePendulum(), torque_limit, posture=[0.0, 0.0, 0.0], spread=[0.5, 0.3, 0.3],
                         amplitude=[0.3, 0.3, 0.3], coordinates=[x, th1, th2], params=params, **kwargs,
                         points=[(x - 0.15, 0), (x + 0.15, 0), tuple(pivot), tuple(elbow), tuple(elbow + l2 * up(th1 + th2))])  # fmt: skip
