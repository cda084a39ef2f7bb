"""Error bounds for tests that compare two floating-point computations (docs/conventions.md, "Tests and
tolerances"): what two correct but differently rounded computations may differ by, on any machine and
any BLAS kernel, so that a tolerance is derived, not read off one machine's run."""

from __future__ import annotations

import numpy as np
import scipy.linalg

EPS = np.finfo(float).eps


def eigenvalue_accuracy(A, lam, balanced: bool = False) -> np.ndarray:
    """Absolute accuracy of computed eigenvalues ``lam`` of ``A``: ``n·eps·‖A‖₂·κ(λ)``.

    The QR algorithm (and a reordered Schur form) is backward stable, ‖δA‖ <= p(n)·eps·‖A‖ with p(n)
    taken as n; to first order an eigenvalue moves by κ(λ)‖δA‖, κ(λ) = ‖y‖‖x‖/|yᴴx| from its left and
    right eigenvectors (Wilkinson). Each ``lam`` gets the κ of the nearest eigenvalue of ``A``. Two
    computations of the same eigenvalue (eigvals of the full model, the Schur form a reduction keeps)
    may differ by twice this. Lightly damped modes of stiff mechanics have ‖A‖ ≈ ω_max² and κ ≈ |λ|/2
    in SI state coordinates, so a low mode is known to ~eps·ω_max²/|λ| relative, not to eps.

    ``balanced=True`` gives the bound of LAPACK's ``geev`` as numpy and scipy call it: it balances first
    (a diagonal similarity by powers of 2, exact), so the backward error is relative to the balanced
    matrix's norm and κ is the balanced one. For closed loops with mixed units (gains ~1e5 beside
    velocities) that is many orders sharper than the unbalanced bound; it does not apply to a Schur form
    computed without balancing.
    """
    A = np.asarray(A, dtype=float)
    if balanced:
        A = scipy.linalg.matrix_balance(A, permute=True, separate=False)[0]
    w, left, right = scipy.linalg.eig(A, left=True, right=True)
    overlap = np.abs(np.sum(left.conj() * right, axis=0))
    kappa = np.linalg.norm(left, axis=0) * np.linalg.norm(right, axis=0) / np.maximum(overlap, 1e-300)
    nearest = np.argmin(np.abs(np.asarray(lam)[:, None] - w[None, :]), axis=1)
    return A.shape[0] * EPS * np.linalg.norm(A, 2) * kappa[nearest]


def transfer_accuracy(A, B, C, D, points, inp: int = 0, out: int = 0) -> np.ndarray:
    """Relative accuracy, per point, of ``H(s) = C (sI − A)⁻¹ B + D`` from a state space, at complex
    ``points`` (s = jω for a continuous system, z = e^{jωT} for a sampled one).

    Two error sources, both normwise: forming the realisation (series, feedback and tf-to-ss products
    round each entry of A relative to the largest operands, ‖δA‖ <= n·eps·‖A‖) and the LU solve of
    (jωI − A) x = B (backward stable, the same form). To first order x moves by κ₂(jωI − A)·n·eps
    relative, and ``C x + D`` loses ``‖C‖‖x‖/|H|`` of it to cancellation where |H| is far below
    ‖C‖‖x‖ (a closed loop above its resonances). A componentwise (Skeel) bound would be sharper for the
    solve alone but does not cover the rounding of A's formation, which is what python-control's
    cascades are limited by (observed 1.1e-7 at 2 kHz, 1e5 times a componentwise solve bound). With
    states in mixed units (m and m/s beside N/m ≈ 1e6) κ₂ makes the bound pessimistic, never invalid."""
    A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C, D))
    n = A.shape[0]
    bound = np.empty(len(points))
    for i, point in enumerate(points):
        M = point * np.eye(n) - A
        x = np.linalg.solve(M, B[:, inp])
        H = C[out] @ x + D[out, inp]
        bound[i] = n * np.linalg.cond(M) * EPS * np.linalg.norm(C[out]) * np.linalg.norm(x) / abs(H)
    return bound


def diagonal_accuracy(A, B, C, points, inp: int = 0, out: int = 0) -> np.ndarray:
    """Relative accuracy, per point, of ``H(p) = Σᵢ (C vᵢ)(wᵢᴴ B)/(p − λᵢ)`` from an eigen-decomposition
    (the diagonal strategy of ``sicomat.lti.response``): its contract
    ``n·eps·κ₂(V)·Σᵢ‖C vᵢ‖‖wᵢᴴB‖/|p − λᵢ| / |H|`` for the residues (eigenvectors are known to
    ``n·eps·κ₂(V)`` relative, backward stable QR), plus ``Σᵢ |rᵢ|·δλᵢ/|p − λᵢ|² / |H|`` for the poles,
    ``δλᵢ`` from :func:`eigenvalue_accuracy` (balanced, as geev computes them)."""
    A, B, C = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C))
    n = A.shape[0]
    lam, V = scipy.linalg.eig(A)
    W = np.linalg.inv(V)
    c = np.abs(C[out] @ V)
    b = np.abs(W @ B[:, inp])
    dlam = eigenvalue_accuracy(A, lam, balanced=True)
    kappa = np.linalg.cond(V)
    p = np.asarray(points, dtype=complex)
    dist = np.abs(p[:, None] - lam[None, :])
    H = (C[out] @ V) @ ((W @ B[:, inp])[:, None] / (p[None, :] - lam[:, None]))
    return (n * EPS * kappa * (c * b / dist).sum(axis=1) + (c * b * dlam / dist ** 2).sum(axis=1)) / np.abs(H)


def exact_transfer(A, B, C, points, inp: int = 0, out: int = 0) -> np.ndarray:
    """``C (pI − A)⁻¹ B`` of the double-precision ``A, B, C`` and points, in exact rational complex
    arithmetic (Gaussian elimination on pairs of Fractions), rounded once to complex128 at the end:
    an oracle accurate to ``eps`` relative. Small systems only (cost grows fast with n)."""
    from fractions import Fraction as F

    A, B, C = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C))
    n = A.shape[0]

    def mul(a, c):
        return (a[0] * c[0] - a[1] * c[1], a[0] * c[1] + a[1] * c[0])

    def div(a, c):
        d = c[0] * c[0] + c[1] * c[1]
        return ((a[0] * c[0] + a[1] * c[1]) / d, (a[1] * c[0] - a[0] * c[1]) / d)

    result = []
    for p in np.asarray(points, dtype=complex):
        M = [[(F(float(p.real)) * (i == j) - F(float(A[i, j])), F(float(p.imag)) * (i == j)) for j in range(n)]
             + [(F(float(B[i, inp])), F(0))] for i in range(n)]
        for k in range(n):
            piv = next(i for i in range(k, n) if M[i][k] != (0, 0))
            M[k], M[piv] = M[piv], M[k]
            for i in range(k + 1, n):
                if M[i][k] != (0, 0):
                    f = div(M[i][k], M[k][k])
                    for j in range(k, n + 1):
                        t = mul(f, M[k][j])
                        M[i][j] = (M[i][j][0] - t[0], M[i][j][1] - t[1])
        x: list = [None] * n
        for i in reversed(range(n)):
            acc = M[i][n]
            for j in range(i + 1, n):
                t = mul(M[i][j], x[j])
                acc = (acc[0] - t[0], acc[1] - t[1])
            x[i] = div(acc, M[i][i])
        re = sum(F(float(C[out, i])) * x[i][0] for i in range(n))
        im = sum(F(float(C[out, i])) * x[i][1] for i in range(n))
        result.append(complex(float(re), float(im)))
    return np.array(result)
