"""Controllers for RollingDisk-v0: LQR (python-control) and a cascaded PD steering law.

Both act on the reduced state ``x = (heading, lean, dheading, dlean, dspin)``
(see :meth:`mbs_envs.models.RollingDisk.reduced_dynamics`) and follow the
commanded heading by leaning into the turn. For the commanded spin ``W`` and
heading rate ``Omega`` the lean of steady circular rolling solves
(:func:`mbs_envs.models.rolling_disk.steady_turn_residual`, also behind the model's
:meth:`~mbs_envs.models.RollingDisk.steady_turning_spin`)

    F(lean; W, Omega) = (C + m r^2) W Omega cos(lean)
                        + (C - A + m r^2) Omega^2 sin(lean) cos(lean) + m g r sin(lean) = 0,

and its rate follows from ``dF = 0``: ``dlean = -(dF/dOmega) dOmega / (dF/dlean)``.
Regulating toward lean 0 instead would fight the lean every turn needs.
The reference state is ``x_ref = (heading_ref, lean_ref, Omega, dlean_ref, W)``
and the error ``z = x - x_ref``.
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from mbs_envs import validation as check
from mbs_envs.envs.rolling_disk import RollingDiskEnv
from mbs_envs.models.rolling_disk import steady_turn_residual

from .base import Controller, linearize
from .tuned import tuned_gains


def steady_lean(
    model: Any, W: Any, Omega: Any, dOmega: Any = 0.0, iterations: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """Lean of steady turning at spin ``W`` and heading rate ``Omega``, and its rate.

    Newton's method on ``F`` (:func:`mbs_envs.models.rolling_disk.steady_turn_residual`) from the small-angle root
    ``lean = -(C + m r^2) W Omega / (m g r + (C - A + m r^2) Omega^2)``
    (batched; four iterations reach rounding for the turns of RollingDisk-v0,
    ``|Omega| <= 0.5`` rad/s, where ``|lean| < 0.1``).

    Parameters
    ----------
    model : RollingDisk
    W, Omega, dOmega : array_like, broadcast to ``(...)``
        Spin [rad/s], heading rate [rad/s], its derivative [rad/s^2].

    Returns
    -------
    lean, dlean : ndarray, shape (...)
        [rad], [rad/s].
    """
    W, Omega, dOmega = np.broadcast_arrays(*(np.asarray(x, float) for x in (W, Omega, dOmega)))
    a, b, c = model.steady_turning_coefficients()
    lean = -a * W * Omega / (c + b * Omega**2)
    for _ in range(iterations):
        F, dF, _ = steady_turn_residual(lean, W, Omega, a, b, c)
        lean = lean - F / dF
    _, dF_dlean, dF_dOmega = steady_turn_residual(lean, W, Omega, a, b, c)
    return lean, -dF_dOmega * dOmega / dF_dlean


def reference_error(model: Any, obs: Any) -> np.ndarray:
    """``z = x - x_ref`` (module docstring) from a decoded observation, shape ``(..., 5)``."""
    lean_ref, dlean_ref = steady_lean(model, obs.spin_ref, obs.dheading_ref, obs.ddheading_ref)
    return np.stack(
        [-obs.heading_error, obs.lean - lean_ref, obs.dheading - obs.dheading_ref, obs.dlean - dlean_ref,
         obs.dspin - obs.spin_ref],
        axis=-1,
    )  # fmt: skip


def weights(value: Any, n: int, name: str) -> np.ndarray:
    """A symmetric positive semi-definite ``n x n`` weight from a diagonal or a matrix."""
    W = check.reals(value, name)
    W = np.diag(W) if W.ndim == 1 else W
    if W.shape != (n, n) or not np.all(np.isfinite(W)) or not np.allclose(W, W.T):
        raise ValueError(f"{name} must be a finite symmetric {n} x {n} matrix or {n} diagonal entries, got {value!r}")
    if np.min(np.linalg.eigvalsh(W)) < -1e-12 * max(1.0, np.max(np.abs(W))):
        raise ValueError(f"{name} must be positive semi-definite, got {value!r}")
    return W


class LQR(Controller):
    """LQR about the commanded steady turn, with integral action on the heading.

    Input ``u = u_ff - K(W) [z; z_I]`` with ``z`` the error from the steady
    turn (module docstring) and ``z_I = int (heading - heading_ref) dt`` the
    heading error's integral (kept in SB3's ``state``, clamped to
    ``+-integral_limit`` rad s against wind-up). The feedforward ``u_ff`` holds
    the reference's heading acceleration and the spin: it solves the heading
    and spin rows of ``dx/dt = f(x_ref, u_ff)`` with the input matrix of the
    linearization. ``K(W)`` comes from ``control.lqr`` on the reduced dynamics
    linearized about upright straight rolling at spin ``W`` (central finite
    differences of the same ``forward_dynamics`` the simulation uses), with the
    heading integral appended; it is solved once, at construction, on a grid
    of spins (``|W|`` from 0.15 to 3 critical spins, 40 per sign) and
    interpolated linearly, never re-solved per call (below 0.15 ``W_c`` the lean
    is nearly uncontrollable by steering and the gain of 0.15 ``W_c`` is used).

    Weights are in the units of the actuator range: ``R`` weighs the
    normalized input ``u / u_max``.

    Parameters
    ----------
    env : gymnasium.Env
        A RollingDisk-v0 environment (wrapped or not).
    Q : array_like (5,) or (5, 5), optional
        Weights on ``z``; default the tuned ones (``controllers/tuned.json``).
    R : array_like (2,) or (2, 2), optional
        Weights on ``u / u_max``; default the tuned ones.
    q_integral : float, optional
        Weight on ``z_I``; 0 switches integral action off.
    integral_limit : float
        Clamp of ``|z_I|`` [rad s].
    heading_error_limit : float
        The heading error the controller acts on is clamped to this [rad]: a
        large error (a start far off the reference) asks for a gentle turn
        instead of a lean the disk cannot hold at low spin.
    """

    fits = (RollingDiskEnv,)

    n_grid = 40
    grid_span = (0.15, 3.0)  # |W| / W_c
    #: the entry of controllers/tuned.json
    tuned_name = "LQR"

    def __init__(self, env: Any, Q: Any = None, R: Any = None, q_integral: Any = None, integral_limit: float = 1.0,
                 heading_error_limit: float = 0.3):  # fmt: skip
        super().__init__(env)
        tuned = tuned_gains(env, "LQR")
        self.Q = weights(tuned["Q"] if Q is None else Q, 5, "Q")
        self.R = weights(tuned["R"] if R is None else R, 2, "R")
        self.q_integral = check.nonnegative(tuned["q_integral"] if q_integral is None else q_integral, "q_integral")
        self.integral_limit = check.positive(integral_limit, "integral_limit")
        self.heading_error_limit = check.positive(heading_error_limit, "heading_error_limit")
        if np.min(np.linalg.eigvalsh(self.R)) <= 0:
            raise ValueError(f"R must be positive definite, got {R!r}")
        self.dt = float(env.unwrapped.dt)
        Wc = self.model.critical_spin
        half = np.geomspace(self.grid_span[0] * Wc, self.grid_span[1] * Wc, self.n_grid)
        self.W_grid = np.concatenate([-half[::-1], half])
        self.K_grid, self.B_grid = self._schedule(self.W_grid)

    def operating_input(self, W: Any) -> np.ndarray:
        """Inputs holding steady straight rolling at spin ``W``: the drive against rolling resistance, ``(..., 2)``."""
        W = np.asarray(W, float)
        return np.stack([self.model.params.b_roll * W, np.zeros_like(W)], axis=-1)

    def system(self, W: float) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` of the reduced dynamics linearized about upright rolling at spin ``W``."""
        return linearize(self.model.reduced_dynamics, np.array([0.0, 0.0, 0.0, 0.0, W]), self.operating_input(W))

    def augmented(self, W: float) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` with the heading integral appended as a sixth state (``d z_I / dt = z_0``)."""
        A, B = self.system(W)
        Aa = np.zeros((6, 6))
        Aa[:5, :5] = A
        Aa[5, 0] = 1.0
        return Aa, np.vstack([B, np.zeros((1, 2))])

    def _schedule(self, W_grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        S = np.diag(self.u_max)  # u = S u_n: weights on the normalized input
        R_phys = np.linalg.inv(S) @ self.R @ np.linalg.inv(S)
        K_grid, B_grid = [], []
        for W in W_grid:
            A, B = self.augmented(W)
            Q = np.zeros((6, 6))
            Q[:5, :5] = self.Q
            Q[5, 5] = self.q_integral
            n = 6 if self.q_integral > 0 else 5
            K, _, _ = control.lqr(A[:n, :n], B[:n], Q[:n, :n], R_phys)
            K_full = np.zeros((2, 6))
            K_full[:, :n] = np.asarray(K)
            K_grid.append(K_full)
            B_grid.append(B[:5])
        return np.array(K_grid), np.array(B_grid)

    def gain(self, W: Any) -> np.ndarray:
        """``K(W)`` (2 x 6, the last column on ``z_I``) interpolated on the grid, shape ``(..., 2, 6)``."""
        return _interpolate(self.W_grid, self.K_grid, W)

    def feedforward(self, obs: Any, z: np.ndarray) -> np.ndarray:
        """``u_ff`` of the class docstring, shape ``(..., 2)``."""
        W = np.asarray(obs.spin_ref, float)
        lean_ref, dlean_ref = steady_lean(self.model, W, obs.dheading_ref, obs.ddheading_ref)
        x_ref = np.stack([np.zeros_like(W), lean_ref, obs.dheading_ref + 0 * W, dlean_ref, W], axis=-1)
        u_op = self.operating_input(W)
        f = self.model.reduced_dynamics(x_ref, u_op)
        B = _interpolate(self.W_grid, self.B_grid, W)[..., [2, 4], :]  # heading and spin rows
        want = np.stack([obs.ddheading_ref + 0 * W, np.zeros_like(W)], axis=-1) - f[..., [2, 4]]
        return u_op + np.linalg.solve(B, want[..., None])[..., 0]

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        z = reference_error(self.model, obs)
        z[..., 0] = np.clip(z[..., 0], -self.heading_error_limit, self.heading_error_limit)
        lead = z.shape[:-1]
        z_i = np.zeros(lead) if state is None else check.shaped(state, "state", lead)
        if episode_start is not None:
            z_i = np.where(
                check.shaped(episode_start, "episode_start", lead, bools=True, broadcast=True) != 0, 0.0, z_i
            )
        z_i = np.clip(z_i + self.dt * z[..., 0], -self.integral_limit, self.integral_limit)
        za = np.concatenate([z, z_i[..., None]], axis=-1)
        u = self.feedforward(obs, z) - np.einsum("...ij,...j->...i", self.gain(obs.spin_ref), za)
        return u, z_i

    def input(self, obs: Any) -> np.ndarray:
        """Inputs without memory (integral state zero)."""
        return self.control(obs, None, None)[0]


def _interpolate(grid: np.ndarray, values: np.ndarray, x: Any) -> np.ndarray:
    """Piecewise-linear ``values(x)`` on an increasing ``grid`` (clamped at its ends), batched over ``x``."""
    x = np.clip(np.asarray(x, float), grid[0], grid[-1])
    i = np.clip(np.searchsorted(grid, x) - 1, 0, len(grid) - 2)
    w = ((x - grid[i]) / (grid[i + 1] - grid[i]))[(...,) + (None,) * (values.ndim - 1)]
    return (1 - w) * values[i] + w * values[i + 1]


class SteeringPD(Controller):
    """A cascaded PD steering law: heading error -> desired turn -> desired lean -> steer.

    ``Omega_d = dheading_ref + k_h wrap(heading_ref - heading)`` is the turn
    rate wanted, ``lean_d`` the steady lean of that turn (module docstring),
    and

        steer = -k_dlean (dlean - dlean_ref) - k_lean (lean - lean_d) + k_r (Omega_d - dheading),
        drive = k_w (W_ref - dspin).

    Steering on the lean rate adds to the gyroscopic coupling
    ``A heading'' = -C W lean' + steer`` exactly as extra spin would, which
    raises the stiffness of the lean against gravity (see
    :func:`mbs_envs.models.rolling_disk.critical_spin`); the heading loop acts
    through the lean, as a rider does, because a direct steering torque toward
    the target opposes the lean the turn needs (non-minimum phase).
    Gains in N m per rad (or rad/s), ``k_h`` in 1/s; defaults the tuned ones.
    """

    fits = (RollingDiskEnv,)

    names = ("k_dlean", "k_lean", "k_h", "k_r", "k_w")
    #: the entry of controllers/tuned.json
    tuned_name = "PD steering"

    def __init__(self, env: Any, **gains: Any):
        super().__init__(env)
        unknown = set(gains) - set(self.names)
        if unknown:
            raise ValueError(f"SteeringPD has no gain {sorted(unknown)[0]!r}; gains are {self.names}")
        tuned = tuned_gains(env, "PD steering")
        self.k = {}
        for name in self.names:
            self.k[name] = check.nonnegative(gains.get(name, tuned[name]), name)

    def input(self, obs: Any) -> np.ndarray:
        k = self.k
        Omega_d = obs.dheading_ref + k["k_h"] * obs.heading_error
        lean_d, dlean_d = steady_lean(self.model, obs.spin_ref, Omega_d, obs.ddheading_ref)
        steer = (
            -k["k_dlean"] * (obs.dlean - dlean_d)
            - k["k_lean"] * (obs.lean - lean_d)
            + k["k_r"] * (Omega_d - obs.dheading)
        )
        drive = k["k_w"] * (obs.spin_ref - obs.dspin)
        return np.stack([drive, steer], axis=-1)


class NoControl(Controller):
    """Zero input (the passive disk)."""

    fits = (RollingDiskEnv,)

    def input(self, obs: Any) -> np.ndarray:
        return np.zeros(np.shape(obs.lean) + (self.model.nu,))
