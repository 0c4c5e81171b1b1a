"""The upright balance under the torque limit: what physics allows, and what an LQR catches.

Two figures for a 2R arm with one motor about upright, both on the linearization
``dx/dt = A x + B u`` (``x = (dq, dv)``), ``|u| <= u_max``:

- :func:`saturation_bound` -- **what physics allows.** For an unstable eigenvalue
  ``lambda > 0`` with left eigenvector ``w`` (``w^T A = lambda w^T``) the mode
  ``z = w^T x`` obeys ``dz/dt = lambda z + (w^T B) u``; once ``|z| >= |w^T B| u_max / lambda``
  no admissible input brings it back. A state is catchable only inside every such slab;
  along one coordinate ``j`` (the others zero) that is ``|x_j| < |w^T B| u_max / (lambda |w_j|)``,
  minimized over the unstable modes. It is a necessary condition of the linearization
  (the nonlinear arm near upright is close to it): an offset beyond it is lost whatever the
  controller does.
- :func:`noise_floor` -- **what observation noise allows**: the smallest stationary spread about upright any
  controller achieves with the observations noisy (the LQG optimum as the input weight vanishes).
- :func:`hold_shares` (and :func:`lqg_hold_share`, the best of a grid of LQG controllers) -- **what observation noise
  leaves of a hold**: the share of windows in which given gains with a given filter keep both angles within a
  tolerance on the noisy linearization, by simulation (an estimate, not a bound).
- :func:`estimate_region` -- **what a given feedback catches**, by simulation: states are
  drawn uniformly in a box about upright, then below the level found so far, and each is run in closed loop ``u = clip(-K x)`` on
  the discrete map the env integrates (:func:`controllers.control_map.fast_map`: compiled for the 2R arm), on every plant
  of a set (the nominal and mismatched ones, optionally with the input applied one step late);
  the estimate is the largest level ``c*`` of the LQR's cost-to-go ``x^T S x`` below which no
  sample failed. It is a sampled estimate, not a certificate: the tests check that fresh states
  inside it are caught and that states well outside the saturation bound are not.
  (The box, not the shells of ``S``, is sampled: ``S`` of the acrobot's LQR has eigenvalues from
  0.08 to 1.2e7, so its sublevel sets reach far out along the rates, to states no swing-up produces.)
  - :func:`axis_catch` -- the same, along one coordinate: the largest offset caught.
"""

from __future__ import annotations

# one idea per module; this module serves their names as it always has
from .catch_region import PlantCase, axis_catch, closed_loop_final, estimate_region, saturation_bound  # noqa: F401
from .hold_evaluation import ArmMap, hold_shares  # noqa: F401
from .hold_laws import (  # noqa: F401
    ZeroDynamicsHold, edge_switched, hold_input, recovering, rescuing, zero_dynamics, zero_dynamics_input,
    zero_dynamics_mode,
)  # fmt: skip
from .noise_floor import (  # noqa: F401
    LQG_GRID, discretize, dlqr, lqg_hold_share, lqg_stationary, noise_floor, quiet_riccati, steady_kalman,
)  # fmt: skip
