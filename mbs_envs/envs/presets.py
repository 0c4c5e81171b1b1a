"""Named configurations of the swing-up scenes: published plants and simulation setups.

``gym.make("mbs_envs/Acrobot-v1", preset="dfki_c1")`` builds the scene with a preset's plant,
torque limit, time step, integrator and start; keywords given beside the preset win over it, and a
``params`` mapping is applied on top of the preset's plant (so one parameter can be varied, as a
robustness sweep does). The protocol ids ``mbs_envs/AcrobotDFKI-v1`` and
``mbs_envs/PendubotDFKI-v1`` are the same with the protocol's episode length (10 s, 5,000 steps).

The DFKI double-pendulum benchmark (RealAIGym, ``dfki-ric-underactuated-lab/double_pendulum``)
publishes its identified parameters in its own convention (:class:`DoublePendulumParams`): angles
from hanging, inertias about the joints, and a motor inertia and gear ratio. Its leaderboards
(simulation v2 and robustness v2, ``sim_parameters.py``) simulate the hardware design ``C.1`` with
the identified ``model_1.0``, but set the motor inertia, the damping and the Coulomb friction to zero,
the torque limit to 6 N m on the driven joint and 0 on the passive one, and integrate with RK4 at
``dt = 2 ms`` (the control rate) for 10 s from hanging at rest. The preset ``"dfki_c1"`` is that
setup; :func:`planar2r_params` converts the plant to :class:`~mbs_envs.models.planar2r.Planar2RParams`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class DoublePendulumParams:
    """A double pendulum in the DFKI benchmark's convention (its ``model_parameters.yml``).

    Attributes
    ----------
    m1, m2 : float
        Link masses [kg].
    l1, l2 : float
        Link lengths [m].
    r1, r2 : float
        Joint to centre of mass [m].
    I1, I2 : float
        Link inertias **about the joint** [kg m^2] (``I_com + m r^2``; ours are about the centre of mass).
    b1, b2 : float
        Viscous friction [N m s/rad].
    cf1, cf2 : float
        Coulomb friction [N m] (their law: ``cf arctan(100 v)``).
    Ir : float
        Motor rotor inertia [kg m^2] (enters the mass matrix times the gear ratio squared).
    gr : float
        Gear ratio.
    g : float
        Gravity [m/s^2].
    """

    m1: float
    m2: float
    l1: float
    l2: float
    r1: float
    r2: float
    I1: float
    I2: float
    b1: float
    b2: float
    cf1: float
    cf2: float
    Ir: float
    gr: float
    g: float = 9.81

    def mass_matrix(self, q_dfki: np.ndarray) -> np.ndarray:
        """Their mass matrix ``M(q)`` [kg m^2], shape ``(..., 2, 2)``, from their angles ``q_dfki`` ``(..., 2)``
        (hanging at 0), motor inertia included::

            M11 = I1 + I2 + m2 l1^2 + 2 m2 l1 r2 cos q2 + gr^2 Ir + Ir
            M12 = I2 + m2 l1 r2 cos q2 - gr Ir
            M22 = I2 + gr^2 Ir
        """
        c2 = np.cos(np.asarray(q_dfki, float)[..., 1])
        h = self.m2 * self.l1 * self.r2 * c2
        M = np.empty(c2.shape + (2, 2))
        M[..., 0, 0] = self.I1 + self.I2 + self.m2 * self.l1**2 + 2 * h + self.gr**2 * self.Ir + self.Ir
        M[..., 0, 1] = M[..., 1, 0] = self.I2 + h - self.gr * self.Ir
        M[..., 1, 1] = self.I2 + self.gr**2 * self.Ir
        return M


#: the DFKI benchmark's identified ``design_C.1/model_1.0`` (``model_parameters.yml``)
DFKI_C1 = DoublePendulumParams(
    m1=0.5234602302310271, m2=0.6255677234174437, l1=0.2, l2=0.3, r1=0.2, r2=0.25569305436052964,
    I1=0.031887199591513114, I2=0.05086984812807257, b1=0.001, b2=0.001, cf1=0.16, cf2=0.12,
    Ir=6.287203962819607e-05, gr=6.0, g=9.81,
)  # fmt: skip

#: their angles minus ours: their ``q = 0`` hangs, ours hangs at ``(-pi/2, 0)``
ANGLE_OFFSET = np.array([np.pi / 2, 0.0])


def planar2r_params(p: DoublePendulumParams) -> dict[str, float]:
    """``p`` as :class:`~mbs_envs.models.planar2r.Planar2RParams` keywords, as the leaderboard simulates it.

    Inertias move from the joint to the centre of mass, ``I_com = I - m r^2``. The leaderboard's
    simulation sets the motor inertia, damping and Coulomb friction to zero (``sim_parameters.py``),
    so they are left out (Planar2R has no rotor inertia; its Coulomb law is smoothed differently).

    Raises
    ------
    ValueError
        If an inertia about the joint is below ``m r^2`` (no such rigid link).
    """
    out = {"m1": p.m1, "m2": p.m2, "l1": p.l1, "l2": p.l2, "r1": p.r1, "r2": p.r2, "g": p.g}
    for i in (1, 2):
        m, r, inertia = getattr(p, f"m{i}"), getattr(p, f"r{i}"), getattr(p, f"I{i}")
        if not inertia >= m * r**2:
            raise ValueError(
                f"I{i} = {inertia:g} is below m{i} r{i}^2 = {m * r * r:g}: no rigid link has it about its joint"
            )
        out[f"I{i}"] = inertia - m * r**2
    return out


#: preset name -> the ``gym.make`` keywords it stands for (:mod:`module docstring <mbs_envs.envs.presets>`)
PRESETS: Mapping[str, Mapping[str, Any]] = MappingProxyType({
    "dfki_c1": MappingProxyType({
        "params": MappingProxyType(planar2r_params(DFKI_C1)), "torque_limit": 6.0, "dt": 0.002, "substeps": 1,
        "integrator": "rk4", "start_noise": 0.0,
    }),
})  # fmt: skip

#: the protocol ids: (id, scene class, preset, max_episode_steps)
PROTOCOL_IDS = (
    ("mbs_envs/AcrobotDFKI-v1", "mbs_envs.envs.swingup:AcrobotV1Env", "dfki_c1", 5000),
    ("mbs_envs/PendubotDFKI-v1", "mbs_envs.envs.swingup:PendubotV1Env", "dfki_c1", 5000),
)
#: the protocol plant with the v2 task's reward (:mod:`mbs_envs.envs.swingup_v2`), for training: the protocol's
#: evaluation runs the ids above (the reward plays no part in it); same layout
TRAINING_IDS = (
    ("mbs_envs/AcrobotDFKI-v2", "mbs_envs.envs.swingup_v2:AcrobotV2Env", "dfki_c1", 5000),
    ("mbs_envs/PendubotDFKI-v2", "mbs_envs.envs.swingup_v2:PendubotV2Env", "dfki_c1", 5000),
)


def with_preset(preset: str | None, given: Mapping[str, Any]) -> dict[str, Any]:
    """The keywords ``given`` on top of ``preset``'s (``given`` wins; ``params`` are merged key by key).

    Raises
    ------
    ValueError
        Naming ``preset`` and the known presets, if it is not one.
    """
    if preset is None:
        return dict(given)
    if not isinstance(preset, str) or preset not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)} or None, got {preset!r}")
    out = {k: v for k, v in PRESETS[preset].items()}
    for key, value in given.items():
        if key == "params" and value is not None:
            if not isinstance(value, Mapping):
                raise ValueError(
                    f"params must be a mapping of Planar2R parameters to combine with preset {preset!r}, got {type(value).__name__}"
                )
            value = {**out["params"], **value}
        out[key] = value
    out["params"] = dict(out["params"])
    return out
