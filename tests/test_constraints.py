"""The compiled Schur-complement solve against an independent dense KKT solve."""

from __future__ import annotations

import numpy as np
import pytest

from mbs_envs.dynamics.constraints import constrained_accelerations


def random_problem(rng, B, n=6, k=3):
    A = rng.normal(size=(B, n, n))
    M = A @ np.swapaxes(A, -1, -2) + n * np.eye(n)  # symmetric positive definite
    return M, rng.normal(size=(B, n)), rng.normal(size=(B, k, n)), rng.normal(size=(B, k))


def kkt(M, f, Psi, gamma):
    """``[[M, -Psi^T], [Psi, 0]] [a; lam] = [f; gamma]`` by LAPACK's dense solve, member by member."""
    n, k = M.shape[-1], Psi.shape[-2]
    K = np.zeros(M.shape[:-2] + (n + k, n + k))
    K[..., :n, :n], K[..., :n, n:], K[..., n:, :n] = M, -np.swapaxes(Psi, -1, -2), Psi
    x = np.linalg.solve(K, np.concatenate([f, gamma], axis=-1)[..., None])[..., 0]
    return x[..., :n], x[..., n:]


@pytest.mark.parametrize("conditioning", [True, False])
def test_equals_the_dense_kkt_solve(conditioning):
    rng = np.random.default_rng(0)
    M, f, Psi, gamma = random_problem(rng, 50)
    a, lam, cond = constrained_accelerations(M, f, Psi, gamma, conditioning=conditioning)
    a_ref, lam_ref = kkt(M, f, Psi, gamma)
    np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-12 * np.max(np.abs(a_ref)))
    np.testing.assert_allclose(lam, lam_ref, rtol=0, atol=1e-12 * np.max(np.abs(lam_ref)))
    if conditioning:
        S = Psi @ np.linalg.solve(M, np.swapaxes(Psi, -1, -2))
        w = np.linalg.eigvalsh(S)
        np.testing.assert_allclose(cond, w[:, -1] / w[:, 0], rtol=1e-10)
    else:  # well conditioned: every member took the Cholesky solve of S
        assert np.all(np.isnan(cond))


def test_single_member_equals_its_row_of_a_batch_bit_for_bit():
    rng = np.random.default_rng(1)
    M, f, Psi, gamma = random_problem(rng, 8)
    for conditioning in (True, False):
        a, lam, _ = constrained_accelerations(M, f, Psi, gamma, conditioning=conditioning)
        for b in range(8):
            a1, lam1, _ = constrained_accelerations(M[b], f[b], Psi[b], gamma[b], conditioning=conditioning)
            np.testing.assert_array_equal(a1, a[b])
            np.testing.assert_array_equal(lam1, lam[b])


def test_rank_deficient_constraints_take_the_pseudo_inverse_either_way():
    """A repeated constraint row makes S singular: the certificate fails, the eigendecomposition
    drops the zero eigenvalue, and both settings return the minimum-norm multipliers."""
    rng = np.random.default_rng(2)
    M, f, Psi, gamma = random_problem(rng, 5)
    Psi[:, 2] = Psi[:, 1]
    gamma[:, 2] = gamma[:, 1]  # consistent: the same constraint twice
    (a, lam, cond), (a2, lam2, cond2) = (
        constrained_accelerations(M, f, Psi, gamma, conditioning=c) for c in (True, False)
    )
    np.testing.assert_array_equal(a2, a)
    np.testing.assert_array_equal(lam2, lam)
    assert np.all(cond > 1e12) and np.all(cond2 > 1e12)  # computed where the fast path was refused
    np.testing.assert_allclose(lam[:, 1], lam[:, 2], rtol=1e-8)  # minimum norm: the load is shared
    np.testing.assert_allclose(np.einsum("bkn,bn->bk", Psi, a), gamma, atol=1e-10)
    # the multipliers of the reduced (full-rank) problem, split between the twin rows
    a_ref, lam_ref = kkt(M, f, Psi[:, :2], gamma[:, :2])
    np.testing.assert_allclose(a, a_ref, atol=1e-10)
    np.testing.assert_allclose(lam[:, 1] + lam[:, 2], lam_ref[:, 1], atol=1e-10)


def test_blown_up_members_get_nan_and_the_others_are_unaffected():
    rng = np.random.default_rng(3)
    M, f, Psi, gamma = random_problem(rng, 6)
    a0, lam0, _ = constrained_accelerations(M, f, Psi, gamma)
    M[1] = -M[1]  # not positive definite
    f[2, 0] = np.nan
    Psi[3, 0, 0] = np.inf
    gamma[4, 1] = np.nan
    a, lam, cond = constrained_accelerations(M, f, Psi, gamma)
    bad = np.array([False, True, True, True, True, False])
    assert np.all(np.isnan(a[bad])) and np.all(np.isnan(lam[bad])) and np.all(np.isnan(cond[bad]))
    np.testing.assert_array_equal(a[~bad], a0[~bad])
    np.testing.assert_array_equal(lam[~bad], lam0[~bad])
