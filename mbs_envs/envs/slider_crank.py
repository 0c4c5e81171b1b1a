"""Scene: a slider-crank, written as a user writes a mechanism: its Lagrangian and loop closure, derived.

A crank ``O A`` (length ``r``, angle ``th`` from +x, driven) turns about the origin; a connecting rod ``A B`` (length ``l``, absolute angle
``ps``) joins it to a slider ``B`` on the x axis (position ``s``, prismatic, a viscous load ``b_s`` on it: a pump or
a damper); gravity along -y. ``q = (th, ps, s)``, one degree of freedom: the loop ``A + l (cos ps, sin ps) = (s, 0)``
closed by two holonomic constraints. The crank follows a rippled spin reference (as ``FourBar-v0``'s).
The user code (as docs/tutorial_lagrangian.md writes it) is everything above the registry hooks: 25 lines with
its imports, blank lines not counted.
"""

import math

import sympy as sp

from ..models import symbolic
from ..models.symbolic import dynamicsymbols
from .derived import DerivedTrackingEnv

t = symbolic.time_symbol()
th, ps, s = dynamicsymbols("th ps s")
r, l, m1, m2, m3, g = sp.symbols("r l m1 m2 m3 g")
A = sp.Matrix([r * sp.cos(th), r * sp.sin(th)])  # crank pin
rod = A + l / 2 * sp.Matrix([sp.cos(ps), sp.sin(ps)])  # the rod's centre of mass
speed2 = lambda p: p.diff(t).dot(p.diff(t))  # noqa: E731
T = (m1 * r**2 / 3 * th.diff(t) ** 2  # the crank, a rod about its end
     + m2 * speed2(rod) + m2 * l**2 / 12 * ps.diff(t) ** 2 + m3 * s.diff(t) ** 2) / 2  # fmt: skip
V = g * (m1 * A[1] / 2 + m2 * rod[1])
closure = list(A + l * sp.Matrix([sp.cos(ps), sp.sin(ps)]) - sp.Matrix([s, 0]))
params = {"r": (0.15, "positive"), "l": (0.5, "positive"), "m1": (0.5, "positive"), "m2": (1.0, "positive"),
          "m3": (2.0, "positive"), "g": 9.81, "b_th": (0.01, "nonnegative"), "b_s": (5.0, "nonnegative")}  # fmt: skip
#: the derived model's class (derived and compiled once, then read from the disk cache): ``SliderCrank(m3=4.0)``
SliderCrank = type(symbolic.derive("SliderCrank", [th, ps, s], T, V, params, actuation=[[1.0], [0.0], [0.0]],
                                   damping={th: "b_th", s: "b_s"}, constraints=closure, independent=[th]))  # fmt: skip


class SliderCrankEnv(DerivedTrackingEnv):
    """Slider-crank driving a viscous load, derived from its Lagrangian: the crank follows a rippled spin.

    ## Description

    A crank ``O A`` (length ``r``, angle ``th`` from +x, driven) turns about the origin; a connecting rod ``A B``
    (length ``l``, absolute angle ``ps``) joins it to a slider ``B`` on the x axis (position ``s``, a viscous
    load ``b_s`` on it: a pump or a damper); gravity along -y. ``q = (th, ps, s)`` with one degree of freedom: the
    loop closure ``A + l (cos ps, sin ps) = (s, 0)`` is two holonomic constraints with Lagrange multipliers,
    derived by :func:`mbs_envs.models.symbolic.derive` from the kinetic and potential energy written in the
    module (the user code of ``docs/tutorial_lagrangian.md``). The crank's reference is
    ``c + s t + ripple``, a mean spin ``s ~ U(1, 4)`` rad/s plus a sum of sines, as ``FourBar-v0``'s.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the crank torque over ``torque_limit`` (2.5 N m).
    Finite out-of-range actions saturate; NaN/inf or wrongly shaped actions raise ``ValueError``.

    ## Observation Space

    ``Box((12,), float32)``: ``[cos q (3), sin q (3), v (3), e (1), v_ref (1), a_ref (1)]`` with
    ``q = (th, ps, s)``, the tracking error ``e = wrap(q_ref - q)`` of the tracked coordinate (the crank ``th``) and its
    reference's rate and acceleration (:func:`mbs_envs.envs.tracking.decode_tracking`).

    ## Rewards

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2)`` over the tracked coordinates, default weights
    ``(1, 0.1, 0.001)``; the terms are in ``info`` (``reward_tracking``, ``reward_velocity``, ``reward_effort``).

    ## Starting State

    The reference's centre ``c ~ U(-pi, pi)``, its ripple's amplitude at most 0.5 rad; the start is the reference's
    state plus ``U(-0.1, 0.1)``, assembled on the constraints (``SliderCrank.assemble``) with consistent rates.

    ## Episode End

    Truncation after ``max_episode_steps`` (500, 5 s at ``dt = 0.01``); termination only on divergence
    (``info["diverged"]``; a loop opened beyond 0.01 m counts as divergence).

    ## Arguments

    ``gym.make("mbs_envs/SliderCrank-v0", params=None, torque_limit=2.5, dt=0.01, integrator="rk4", substeps=..., compiled=True,
    render_mode=None)``; ``params`` overrides the derived model's parameters (``r, l, m1, m2, m3, g, b_th, b_s``).

    ## Version History

    - v0: initial version.
    """

    step_kernel = DerivedTrackingEnv.step_kernel  # the same task: its compiled step

    def __init__(self, params=None, torque_limit=2.5, **kwargs):
        super().__init__(SliderCrank(), torque_limit, posture=[0.0], spread=math.pi, amplitude=0.5, rate=(1.0, 4.0),
                         guess=[0.0, 0.0, 0.65], coordinates=[th, ps, s], points=[(0, 0), tuple(A), (s, 0)], params=params, **kwargs)  # fmt: skip
