"""Each scene's numerics cases, as its registry entry names them: the free motions of the work-precision study
(:func:`mbs_envs.studies.work_precision.free_problems`), the stiff and extreme cases and the cases that end at a
coordinate singularity (:func:`mbs_envs.studies.stiff_cases.stiff_cases`, ``singular_cases``).

A free motion is ``(label, model, q0, v0, stabilization)``; a case is a :class:`~mbs_envs.studies.numerics.Case`.
"""

from __future__ import annotations

import numpy as np

from ..envs.cart_double_pendulum import CartDoublePendulum
from ..envs.cart_pole import CartPole
from ..envs.references import SumOfSines
from ..envs.serial_chain import SerialChainEnv
from ..envs.slider_crank import SliderCrank
from ..envs.spatial_chain import SpatialChainEnv, reach_gravity_torque
from ..models import FourBar, Planar2R, RollingDisk, SerialChain, SpatialChain
from .numerics import Case, computed_torque_law, pd_law


# -- planar2r --------------------------------------------------------------------------------------


def planar2r_free_motions() -> list[tuple]:
    """The work-precision study's free motion: the default arm from a bent posture, no input."""
    return [("planar2r", Planar2R(), np.array([-1.0, 0.8]), np.array([0.5, -1.0]), None)]


def planar2r_stiff_cases(quick: bool = False) -> list:
    """Stiff friction (viscous, Coulomb, Stribeck), stiff feedback (PD, computed torque) and
    extreme mass and inertia ratios, 1 s each from one state (``docs/numerics.md``)."""
    q0, v0 = np.array([-1.0, 0.5]), np.array([1.0, -2.0])
    cases = [
        Case("viscous b=400", Planar2R(b1=400.0, b2=400.0), q0, v0, 1.0, u=np.array([30.0, 5.0]),
             conservative=False, reference_method="radau"),
        Case("Coulomb f=2, v_s=1e-4", Planar2R(f1=2.0, f2=2.0, v_s=1e-4), q0, v0, 1.0,
             conservative=False, reference_method="radau"),
        Case("Stribeck f=1, df=1, v_st=0.05, v_s=1e-3", Planar2R(f1=1.0, f2=1.0, df1=1.0, df2=1.0, v_st=0.05, v_s=1e-3),
             q0, v0, 1.0, conservative=False, reference_method="radau"),
        Case("PD kp=1e5, kd=2e3", Planar2R(), q0, v0, 1.0, u=pd_law(1e5, 2e3, np.array([-0.5, 0.5])),
             conservative=False, reference_method="radau"),
    ]  # fmt: skip
    ref = SumOfSines(np.array([-1.2, 0.4]), np.array([[0.3], [0.5]]), np.array([[2.0], [3.0]]), np.zeros((2, 1)))
    m2r = Planar2R()
    cases.append(
        Case("computed torque w=1000", m2r, q0, v0, 1.0, u=computed_torque_law(m2r, ref, 1e6, 2e3),
             conservative=False, reference_method="radau")
    )  # fmt: skip
    for label, kw in {
        "mass ratio 1e-3": {"m1": 1.0, "m2": 1e-3, "I1": 1 / 12, "I2": 1e-3 / 12},
        "mass ratio 1e3": {"m1": 1.0, "m2": 1e3, "I1": 1 / 12, "I2": 1e3 / 12},
        "inertia ratio 1e-3 (r2=0)": {"m2": 1.0, "r2": 0.0, "I2": 1e-3 / 12},
    }.items():
        cases.append(Case(label, Planar2R(**kw), q0, v0, 1.0))
    return cases


# -- fourbar ---------------------------------------------------------------------------------------


def fourbar_free_motions() -> list[tuple]:
    """The work-precision study's free motion: the default linkage turning its crank at 4 rad/s."""
    fb = FourBar()
    return [("fourbar", fb, *fb.consistent_state(0.2, 4.0), "projection")]


def fourbar_stiff_cases(quick: bool = False) -> list:
    """A non-Grashof triple rocker through its toggles, Baumgarte's feedback at stiff gains, and a
    parallelogram through its change point (``docs/numerics.md``)."""
    tr = FourBar(l0=1.0, l1=0.9, l2=0.5, l3=0.7)  # non-Grashof triple rocker: the crank meets toggles
    qt, vt = tr.consistent_state(1.2, 3.0)
    cases = [Case("four-bar toggles (triple rocker)", tr, qt, vt, 2.0, stabilization="projection")]
    q4, v4 = FourBar().consistent_state(0.2, 4.0)
    for gain in (1e2, 1e3):  # Baumgarte's feedback on the residual: fast modes -alpha (twice), stiff at large gains
        cases.append(Case(f"four-bar Baumgarte alpha=beta={gain:g}", FourBar(), q4, v4, 1.0,
                          stabilization=FourBar().stabilization("baumgarte", alpha=gain, beta=gain)))  # fmt: skip
    cp = FourBar(l0=1.0, l1=0.4, l2=1.0, l3=0.4)  # parallelogram: change point at th1 = 0
    qc, vc = cp.consistent_state(0.5, -3.0)
    cases.append(Case("four-bar change point (parallelogram)", cp, qc, vc, 1.0, stabilization="projection"))
    return cases


# -- rolling disk ----------------------------------------------------------------------------------


def rolling_disk_free_motions() -> list[tuple]:
    """The work-precision study's free motion: rolling at twice the critical spin, small lean."""
    disk = RollingDisk()
    qd, vd = disk.rolling_state(lean=0.1, dspin=2.0 * disk.critical_spin, dlean=0.2)
    return [("rollingdisk", disk, qd, vd, "projection")]


def rolling_disk_stiff_cases(quick: bool = False) -> list:
    """Spin rates far above the critical one: the fast gyroscopic mode sets the step."""
    disk = RollingDisk()
    cases = []
    for factor in (10, 100):
        qd, vd = disk.rolling_state(lean=0.1, dspin=factor * disk.critical_spin, dlean=0.2)
        cases.append(Case(f"disk {factor}x critical spin", disk, qd, vd, 1.0, stabilization="projection"))
    return cases


def rolling_disk_singular_cases() -> list:
    """The disk falling flat (lean 1.2 rad, 0.3x the critical spin): its coordinates end singular."""
    disk = RollingDisk()
    q, v = disk.rolling_state(lean=1.2, dspin=0.3 * disk.critical_spin)
    return [Case("disk falls flat", disk, q, v, 3.0, stabilization="projection")]


# -- serial chain ----------------------------------------------------------------------------------


def drive_chain(n: int, armature: bool = True) -> SerialChain:
    """The default rope of ``n`` links: SerialChain-v0's model (its drives' armature), or bare."""
    return SerialChainEnv(n_links=n).model if armature else SerialChain(n_links=n)


def _serial_chain_bent(n: int) -> np.ndarray:
    """The chains' start posture: first link 0.3 rad below horizontal, then bent by 1.5 rad in all."""
    return np.r_[-0.3, np.full(n - 1, 1.5 / n)]


def _chain_free_motions(label: str, drive, bent) -> list[tuple]:
    """Chains of 10 and 50 links with drives, from rest at the posture ``bent(n)``."""
    return [(f"{label}{n}", drive(n), bent(n), np.zeros(n), None) for n in (10, 50)]


def _chain_stiff_cases(label: str, drive, bent, quick: bool) -> list:
    """200 (and, unless ``quick``, 500) links with drives over 5 s; 200 bare links over 0.3 s."""
    cases = [
        Case(f"{label} N={n}, drives", drive(n), bent(n), np.zeros(n), 5.0) for n in ((200,) if quick else (200, 500))
    ]
    cases.append(Case(f"{label} N=200, bare", drive(200, False), bent(200), np.zeros(200), 0.3))
    return cases


def serial_chain_free_motions() -> list[tuple]:
    """The work-precision study's free motions: chains of 10 and 50 links with drives, from rest."""
    return _chain_free_motions("chain", drive_chain, _serial_chain_bent)


def serial_chain_stiff_cases(quick: bool = False) -> list:
    """Long chains: 200 (and, unless ``quick``, 500) links with drives over 5 s; 200 bare links over 0.3 s."""
    return _chain_stiff_cases("chain", drive_chain, _serial_chain_bent, quick)


# -- spatial chain ---------------------------------------------------------------------------------


def spatial_chain_drive_chain(n: int, armature: bool = True) -> SpatialChain:
    """The default spatial chain of ``n`` links: SpatialChain-v0's model (its drives' armature), or bare."""
    model = SpatialChain(n_links=n)
    return (
        model.with_params(
            model.params.replace(armature=reach_gravity_torque(model) / SpatialChainEnv.rotor_acceleration)
        )
        if armature
        else model
    )


def _spatial_chain_bent(n: int) -> np.ndarray:
    """The start posture: out of the rest posture by 0.3 rad at the first bend, then bent by 1.5 rad in all."""
    q = np.full(n, 1.5 / n)
    if n > 1:
        q[1] = np.pi / 2 - 0.3
    return q


def spatial_chain_free_motions() -> list[tuple]:
    """The work-precision study's free motions: spatial chains of 10 and 50 links with drives, from rest."""
    return _chain_free_motions("spatialchain", spatial_chain_drive_chain, _spatial_chain_bent)


def spatial_chain_stiff_cases(quick: bool = False) -> list:
    """Long spatial chains: 200 (and, unless ``quick``, 500) links with drives over 5 s; 200 bare links over 0.3 s."""
    return _chain_stiff_cases("spatial chain", spatial_chain_drive_chain, _spatial_chain_bent, quick)


# -- slider crank ----------------------------------------------------------------------------------


def slider_crank_free_motions() -> list[tuple]:
    """The work-precision study's free motion: the crank turning at 6 rad/s, assembled on the default branch."""
    model = SliderCrank()
    q = model.assemble([0.2], [0.0, 0.0, 0.65])
    return [("slider-crank", model, q, model.complete_velocity(q, [6.0]), "projection")]


# -- cart double pendulum --------------------------------------------------------------------------


def cart_double_pendulum_free_motions() -> list[tuple]:
    """The work-precision study's free motion: released near upright, the chain falls and swings about the cart."""
    model = CartDoublePendulum()
    return [("cart-double-pendulum", model, [0.0, 0.3, -0.2], [0.5, 0.0, 0.0], None)]


# -- cart pole -------------------------------------------------------------------------------------


def cart_pole_free_motions() -> list[tuple]:
    """The work-precision study's free motion: released near upright, the pole falls and swings the cart."""
    return [("cart-pole", CartPole(), [0.0, 0.2], [0.0, 0.0], None)]
