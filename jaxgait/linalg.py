"""Small dense symmetric positive-definite solves, unrolled into elementwise operations.

The step solves two small SPD systems per environment, both 9 x 9: the mass matrix
augmented by the damping of the stiff contact/soft-limit rows (:mod:`jaxgait.rows`), and
the mass matrix itself.  Under
``vmap`` XLA's CPU backend runs ``jnp.linalg`` / ``jax.scipy.linalg`` factorisations as one
LAPACK call per environment, which costs more than the whole multibody forward pass at
batch 512.  Written out entry by entry with static Python loops, a Cholesky factorisation
and its substitutions become a few hundred multiply-adds over the batch axis that XLA fuses
into a handful of vectorised loops.  Use only for small n (the trace grows as n^3 / 6).

No pivoting is needed: the matrices are symmetric positive definite (a mass matrix, and
M + dt J^T C J with J^T C J positive semi-definite).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def cholesky(a: jax.Array) -> jax.Array:
    """Lower-triangular L with L L^T = a for a small SPD matrix a (n, n) (unrolled)."""
    n = a.shape[-1]
    if a.shape != (n, n):
        raise ValueError(f"cholesky expects a square matrix, got shape {a.shape}")
    L = [[None] * n for _ in range(n)]
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        d = jnp.sqrt(s)
        L[j][j] = d
        inv = 1.0 / d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s * inv
    zero = jnp.zeros((), a.dtype)
    return jnp.stack([jnp.stack([L[i][j] if j <= i else zero for j in range(n)]) for i in range(n)])


def cho_solve(L: jax.Array, b: jax.Array) -> jax.Array:
    """x with (L L^T) x = b; b is (n,) or (n, k) (unrolled forward and back substitution)."""
    n = L.shape[-1]
    if b.shape[0] != n:
        raise ValueError(f"cho_solve: right-hand side has {b.shape[0]} rows, matrix has {n}")
    inv = [1.0 / L[i, i] for i in range(n)]
    y = [None] * n
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s = s - L[i, k] * y[k]
        y[i] = s * inv[i]
    x = [None] * n
    for i in reversed(range(n)):  # L^T x = y
        s = y[i]
        for k in range(i + 1, n):
            s = s - L[k, i] * x[k]
        x[i] = s * inv[i]
    return jnp.stack(x)


def spd_solve(a: jax.Array, b: jax.Array) -> jax.Array:
    """x with a x = b for a small SPD matrix a (n, n); b (n,) or (n, k)."""
    return cho_solve(cholesky(a), b)


__all__ = ["cho_solve", "cholesky", "spd_solve"]
