"""Scene: a slider-crank, written as a user writes a mechanism (issue 36): its Lagrangian and loop closure, derived.

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
    """``mbs_envs/SliderCrank-v0``: the crank follows ``c + s t + ripple`` (``s ~ U(1, 4)`` rad/s) with <= 2.5 N m."""

    step_kernel = DerivedTrackingEnv.step_kernel  # the same task: its compiled step

    def __init__(self, params=None, torque_limit=2.5, **kwargs):
        super().__init__(SliderCrank(), torque_limit, posture=[0.0], spread=math.pi, amplitude=0.5, rate=(1.0, 4.0),
                         guess=[0.0, 0.0, 0.65], coordinates=[th, ps, s], points=[(0, 0), tuple(A), (s, 0)], params=params, **kwargs)  # fmt: skip


# -- the project's registry hooks (not user code): the numerics studies' free motion ------------------------------


def free_motions() -> list[tuple]:
    """The work-precision study's free motion: the crank turning at 6 rad/s, assembled on the default branch."""
    model = SliderCrank()
    q = model.assemble([0.2], [0.0, 0.0, 0.65])
    return [("slider-crank", model, q, model.complete_velocity(q, [6.0]), "projection")]
