"""Scene: a cart-pole swing-up, written as a user writes a mechanism (issue 36): its Lagrangian, one input, derived.

A cart (mass ``m0``, position ``x`` on a rail of half-length 2.4 m, driven by a force of at most 10 N) carries a
uniform pole (mass ``m``, length ``l``, angle ``th`` from upright, passive); Gymnasium's CartPole's plant (1 kg cart,
0.1 kg pole 1 m long), with viscous friction on both coordinates. The task is
:class:`~mbs_envs.envs.derived_swingup.DerivedSwingUpEnv`'s: swing the pole up from hanging and hold it, the cart
kept on the rail (leaving it ends the episode). The user code (as docs/tutorial_lagrangian.md writes it) is
everything above the registry hooks: 23 lines with its imports, blank lines not counted.
"""

import math

import sympy as sp

from ..models import symbolic
from ..models.symbolic import dynamicsymbols
from .derived_swingup import DerivedSwingUpEnv

t = symbolic.time_symbol()
x, th = dynamicsymbols("x th")
m0, m, l, g = sp.symbols("m0 m l g")
up = sp.Matrix([sp.sin(th), sp.cos(th)])  # the pole's direction (th from upright)
pivot, centre = sp.Matrix([x, 0]), sp.Matrix([x, 0]) + l / 2 * up
T = (m0 * x.diff(t) ** 2 + m * centre.diff(t).dot(centre.diff(t)) + m * l**2 / 12 * th.diff(t) ** 2) / 2
V = m * g * centre[1]
params = {"m0": (1.0, "positive"), "m": (0.1, "positive"), "l": (1.0, "positive"), "g": 9.81,
          "b_x": (0.1, "nonnegative"), "b_th": (0.002, "nonnegative")}  # fmt: skip
#: the derived model's class (only the cart driven: actuation selects x)
CartPole = type(symbolic.derive("CartPole", [x, th], T, V, params, actuation=[[1.0], [0.0]], damping={x: "b_x", th: "b_th"}))


class CartPoleSwingUpEnv(DerivedSwingUpEnv):
    """``mbs_envs/CartPoleSwingUp-v0``: swing the pole up with <= 10 N on the cart, within +-2.4 m."""

    step_kernel = DerivedSwingUpEnv.step_kernel  # the same task: its compiled step

    def __init__(self, params=None, torque_limit=10.0, substeps=2, **kwargs):
        super().__init__(CartPole(), torque_limit, upright=[0.0, 0.0], hanging=[0.0, math.pi], angles=[th],
                         bounds={x: (-2.4, 2.4)}, coordinates=[x, th], params=params, substeps=substeps, **kwargs,
                         points=[(x - 0.2, 0), (x + 0.2, 0), tuple(pivot), tuple(pivot + l * up)])  # fmt: skip


# -- the project's registry hooks (not user code): the numerics studies' free motion ------------------------------


def free_motions() -> list[tuple]:
    """The work-precision study's free motion: released near upright, the pole falls and swings the cart."""
    return [("cart-pole", CartPole(), [0.0, 0.2], [0.0, 0.0], None)]
