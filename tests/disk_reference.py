"""An independent SymPy model of the rolling disk, for the tests.

Built from rotation matrices (``skew(w) = dR/dt R^T``), the body inertia, and
the contact point found as the lowest point of the rim; accelerations from the
KKT system solved directly (not the Schur complement the package uses).
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

from tests.lagrange import lagrange


@functools.lru_cache(maxsize=None)
def disk_functions():
    x, y, z, th1, th2, th3 = q = list(sp.symbols("x y z th1 th2 th3"))
    dq = list(sp.symbols("dx dy dz dth1 dth2 dth3"))
    m, r, g = sp.symbols("m r g", positive=True)
    c, s = sp.cos, sp.sin
    Rz = sp.Matrix([[c(th1), -s(th1), 0], [s(th1), c(th1), 0], [0, 0, 1]])
    Rx = sp.Matrix([[1, 0, 0], [0, c(th2), -s(th2)], [0, s(th2), c(th2)]])
    Ry = sp.Matrix([[c(th3), 0, s(th3)], [0, 1, 0], [-s(th3), 0, c(th3)]])
    R = Rz * Rx * Ry
    Rdot = sum((R.diff(qi) * dqi for qi, dqi in zip(q, dq)), sp.zeros(3, 3))
    W = sp.simplify(Rdot * R.T)
    w = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
    I_body = sp.diag(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4)
    T = (
        sp.Rational(1, 2) * m * (dq[0] ** 2 + dq[1] ** 2 + dq[2] ** 2)
        + sp.Rational(1, 2) * (w.T * R * I_body * R.T * w)[0]
    )
    V = m * g * z
    M, Cv, G = lagrange(sp.expand(T), V, q, dq, simplify=False)
    n = R * sp.Matrix([0, 1, 0])
    ez = sp.Matrix([0, 0, 1])
    down = -(ez - n[2] * n)
    rC = r * down / sp.sqrt(1 - n[2] ** 2)  # lowest point of the rim (valid while not flat)
    vC = sp.Matrix(dq[:3]) + w.cross(rC)
    Psi = vC.jacobian(dq)
    dPsi_v = (Psi * sp.Matrix(dq)).jacobian(q) * sp.Matrix(dq)
    args = [m, r, g] + q + dq
    f = {
        k: sp.lambdify(args, e, "numpy")
        for k, e in dict(M=M, Cv=Cv, G=G, Psi=Psi, dPsi_v=dPsi_v, T=T, R=R, rC=rC).items()
    }
    return f


def kkt_accelerations(m, r, g, q, v, Q):
    """Accelerations and multipliers from [[M, -Psi^T], [Psi, 0]] [a; lam] = [Q - Cv - G; -dPsi v]."""
    f = disk_functions()
    args = [m, r, g, *q, *v]
    M = np.array(f["M"](*args), float)
    Psi = np.array(f["Psi"](*args), float)
    rhs = np.r_[Q - np.ravel(f["Cv"](*args)) - np.ravel(f["G"](*args)), -np.ravel(f["dPsi_v"](*args))]
    K = np.block([[M, -Psi.T], [Psi, np.zeros((3, 3))]])
    sol = np.linalg.solve(K, rhs)
    return sol[:6], sol[6:]
