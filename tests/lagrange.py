"""Independent equations of motion by SymPy: Lagrange's equations from kinematics.

Used by the tests as the reference the models are checked against; shares no
code with ``mbs_envs``.
"""

from __future__ import annotations

import sympy as sp


def lagrange(T: sp.Expr, V: sp.Expr, q: list, dq: list, simplify: bool = True):
    """Equations of motion by Lagrange: ``d/dt dL/d(dq) - dL/dq = M ddq + h``.

    The time derivative is taken literally by the chain rule with symbols for
    ``ddq``; ``M`` is the coefficient of ``ddq``, the remainder at ``ddq = 0``
    splits into gravity ``G = dV/dq`` and velocity terms ``C v``.

    Returns
    -------
    M : sympy.Matrix (n, n)
    Cv : sympy.Matrix (n, 1)
    G : sympy.Matrix (n, 1)
    """
    n = len(q)
    ddq = sp.symbols(f"ddq1:{n + 1}")
    L = T - V
    eqs = []
    for i in range(n):
        p = sp.diff(L, dq[i])
        dpdt = sum(sp.diff(p, q[j]) * dq[j] + sp.diff(p, dq[j]) * ddq[j] for j in range(n))
        eqs.append(sp.expand(dpdt - sp.diff(L, q[i])))
    M = sp.Matrix(n, n, lambda i, j: sp.diff(eqs[i], ddq[j]))
    rest = sp.Matrix([e.subs({a: 0 for a in ddq}) for e in eqs])
    G = sp.Matrix([sp.diff(V, qi) for qi in q])
    Cv = sp.expand(rest - G)
    if not simplify:  # large expressions: leave them to lambdify
        return M, Cv, G
    return sp.simplify(M), sp.simplify(Cv), sp.simplify(G)


def planar_chain(n: int):
    """Symbols and energies of a planar chain of ``n`` links with relative angles.

    Link i: mass ``m_i``, length ``l_i``, COM at ``r_i`` along the link,
    inertia ``I_i`` about its COM; ``q_1`` from +x, gravity ``g`` along -y.

    Returns
    -------
    dict with keys q, dq, syms (parameter symbols by name), T, V
    """
    q = list(sp.symbols(f"q1:{n + 1}"))
    dq = list(sp.symbols(f"dq1:{n + 1}"))
    syms = {}
    for k in ("m", "l", "r", "I"):
        for i in range(1, n + 1):
            syms[f"{k}{i}"] = sp.Symbol(f"{k}{i}", positive=True)
    g = syms["g"] = sp.Symbol("g")
    T = 0
    V = 0
    base = sp.Matrix([0, 0])
    angle = 0
    dangle = 0
    for i in range(1, n + 1):
        angle = angle + q[i - 1]
        dangle = dangle + dq[i - 1]
        u = sp.Matrix([sp.cos(angle), sp.sin(angle)])
        com = base + syms[f"r{i}"] * u
        vcom = com.jacobian(q) * sp.Matrix(dq)
        T += sp.Rational(1, 2) * syms[f"m{i}"] * (vcom.T * vcom)[0] + sp.Rational(1, 2) * syms[f"I{i}"] * dangle**2
        V += syms[f"m{i}"] * g * com[1]
        base = base + syms[f"l{i}"] * u
    return {"q": q, "dq": dq, "syms": syms, "T": sp.expand(T), "V": V}
