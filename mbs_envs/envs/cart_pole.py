"""Scene: a cart-pole swing-up, written as a user writes a mechanism: its Lagrangian, one input, derived.

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
CartPole = type(
    symbolic.derive("CartPole", [x, th], T, V, params, actuation=[[1.0], [0.0]], damping={x: "b_x", th: "b_th"})
)


class CartPoleSwingUpEnv(DerivedSwingUpEnv):
    """Cart-pole, derived from its Lagrangian, one input: swing the pole up from hanging and balance it on the rail.

    ## Description

    Gymnasium's CartPole plant (a 1 kg cart on a rail of half-length 2.4 m, a uniform 0.1 kg pole 1 m long), with
    viscous friction on both coordinates, derived by :func:`mbs_envs.models.symbolic.derive` from the energies
    written in the module. Only the cart is driven (at most 10 N); the pole starts hanging and must be swung up
    and held upright while the cart stays on the rail.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the cart force over ``torque_limit`` (10 N).

    ## Observation Space

    ``Box((5,), float32)``: ``[cos th, sin th, x, dx, dth]`` (``th`` from upright).

    ## Rewards

    ``r = w_h h - w_e |e|^2 - w_u |action|^2 + w_b 1[upright] + r_x`` with ``(w_h, w_e, w_u) = (1, 0.05, 0.01)``
    and ``w_b = 1``: ``h`` the potential energy between hanging (-1) and upright (+1), ``e`` the pole's error from
    upright, ``upright`` the pole within ``upright_tolerance`` (0.1 rad). Leaving the rail terminates the
    episode with ``r_x`` the largest loss the remaining steps could cost on the rail, so running off never
    scores more than staying on (:mod:`mbs_envs.envs.derived_swingup`).

    ## Starting State

    Hanging: ``q0 = (0, pi) + U(-0.1, 0.1)``, ``v0 = U(-0.1, 0.1)``; or exactly
    ``reset(options={"q": ..., "v": ...})``.

    ## Episode End

    Truncation after 1000 steps (10 s); termination on leaving the rail or on divergence. An episode
    *succeeds* when the pole stays within 0.1 rad of upright for its last 2 s.

    ## Arguments

    ``gym.make("mbs_envs/CartPoleSwingUp-v0", params=None, torque_limit=10.0, substeps=2, dt=0.01,
    integrator="rk4", reward_weights=(1, 0.05, 0.01), hold_bonus=1.0, upright_tolerance=0.1, start_noise=0.1,
    horizon=1000, compiled=True, render_mode=None)``; ``params`` overrides ``m0, m, l, g, b_x, b_th``.

    ## Version History

    - v0: initial version.
    """

    step_kernel = DerivedSwingUpEnv.step_kernel  # the same task: its compiled step

    def __init__(self, params=None, torque_limit=10.0, substeps=2, **kwargs):
        super().__init__(CartPole(), torque_limit, upright=[0.0, 0.0], hanging=[0.0, math.pi], angles=[th],
                         bounds={x: (-2.4, 2.4)}, coordinates=[x, th], params=params, substeps=substeps, **kwargs,
                         points=[(x - 0.2, 0), (x + 0.2, 0), tuple(pivot), tuple(pivot + l * up)])  # fmt: skip
