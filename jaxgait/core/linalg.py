"""Small dense symmetric positive-definite solves, unrolled into elementwise operations.

The step solves two small SPD systems per environment, both 9 x 9: the mass matrix
augmented by the damping of the stiff contact/soft-limit rows (:mod:`jaxgait.sim.rows`), and
the mass matrix itself.  Both have the sparsity of the kinematic tree, which
``spd_solve(..., parents)`` exploits.  Under
``vmap`` XLA's CPU backend runs ``jnp.linalg`` / ``jax.scipy.linalg`` factorisations as one
LAPACK call per environment, which costs more than the whole multibody forward pass at
batch 512.  Written out entry by entry with static Python loops, a Cholesky factorisation
and its substitutions become a few hundred multiply-adds over the batch axis that XLA fuses
into a handful of vectorised loops.  Use only for small n (the trace grows as n^3 / 6).

No pivoting is needed: the matrices are symmetric positive definite (a mass matrix, and
M + dt J^T C J with J^T C J positive semi-definite).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp


def cholesky(a: jax.Array) -> jax.Array:
    """Lower-triangular L with L L^T = a for a small SPD matrix a (n, n) (unrolled)."""
    n = a.shape[-1]
    if a.shape != (n, n):
        raise ValueError(f"cholesky expects a square matrix, got shape {a.shape}")
    return _factor(a, *_dense(n))


def cho_solve(L: jax.Array, b: jax.Array) -> jax.Array:
    """x with (L L^T) x = b; b is (n,) or (n, k) (unrolled forward and back substitution)."""
    n = L.shape[-1]
    if b.shape[0] != n:
        raise ValueError(f"cho_solve: right-hand side has {b.shape[0]} rows, matrix has {n}")
    return _substitute(L, b, *_dense(n))


def spd_solve(a: jax.Array, b: jax.Array, parents: tuple[int, ...] | None = None) -> jax.Array:
    """x with a x = b for a small SPD matrix a (n, n); b (n,) or (n, k).

    ``parents`` (static): the parent of each degree of freedom in a kinematic tree (-1 for a
    root; MuJoCo's ``dof_parentid``, every parent before its children).  Then ``a`` is taken
    to couple only a degree of freedom with its ancestors (a joint-space mass matrix, plus
    terms J^T C J of rows that each act on one chain of the tree); its other entries are not
    read.  Eliminating from the leaves towards the root creates no fill-in (as MuJoCo's own
    factorisation of M), so the factorisation and substitutions skip every structural zero:
    for the planar body (3 root and 2 x 3 leg degrees of freedom) about half of the dense work.
    """
    n = a.shape[-1]
    if a.shape != (n, n) or b.shape[0] != n:
        raise ValueError(f"spd_solve: matrix of shape {a.shape}, right-hand side {b.shape}")
    pattern = _dense(n) if parents is None else _tree_elimination(tuple(parents), n)
    # the factor goes through one stacked array before the substitutions: fused straight
    # into them, XLA's CPU code rounded differently with the number of host devices, and
    # results must not depend on the sharding (tests/test_objective.py)
    return _substitute(_factor(a, *pattern), b, *pattern)


def _factor(a, order, nz) -> jax.Array:
    """Cholesky factor (n, n) of the permuted matrix P a P^T (row i of P a P^T is row
    ``order[i]`` of a), computing only the entries nz[i][j] (i > j) and the diagonal."""
    n = len(order)
    L = {}
    for j in range(n):
        s = a[order[j], order[j]]
        for k in range(j):
            if nz[j][k]:
                s = s - L[j, k] * L[j, k]
        L[j, j] = jnp.sqrt(s)
        inv = 1.0 / L[j, j]
        for i in range(j + 1, n):
            if nz[i][j]:
                s = a[order[i], order[j]]
                for k in range(j):
                    if nz[i][k] and nz[j][k]:
                        s = s - L[i, k] * L[j, k]
                L[i, j] = s * inv
    zero = jnp.zeros((), a.dtype)
    return jnp.stack([jnp.stack([L.get((i, j), zero) for j in range(n)]) for i in range(n)])


def _substitute(L, b, order, nz) -> jax.Array:
    """x with a x = b from the factor L of P a P^T (:func:`_factor`)."""
    n = len(order)
    inv = [1.0 / L[i, i] for i in range(n)]
    y = [None] * n
    for i in range(n):  # L y = P b
        s = b[order[i]]
        for k in range(i):
            if nz[i][k]:
                s = s - L[i, k] * y[k]
        y[i] = s * inv[i]
    x = [None] * n
    for i in reversed(range(n)):  # L^T x' = y, x = P^T x'
        s = y[i]
        for k in range(i + 1, n):
            if nz[k][i]:
                s = s - L[k, i] * x[k]
        x[i] = s * inv[i]
    out = [None] * n
    for i in range(n):
        out[order[i]] = x[i]
    return jnp.stack(out)


@functools.cache
def _dense(n: int):
    """(order, nz) of a dense matrix: natural order, every entry below the diagonal."""
    return tuple(range(n)), tuple(tuple(k < i for k in range(n)) for i in range(n))


@functools.cache
def _tree_elimination(parents: tuple[int, ...], n: int):
    """(order, nz): leaves-first elimination order of a kinematic tree and the structural
    nonzeros nz[i][j] (i > j, positions in that order) of the Cholesky factor."""
    if len(parents) != n or any(not -1 <= p < i for i, p in enumerate(parents)):
        raise ValueError(f"parents {parents} must list, for each of {n} dofs, an earlier dof or -1")
    order = tuple(reversed(range(n)))  # every dof before its ancestors
    pos = {d: i for i, d in enumerate(order)}
    nz = [[False] * n for _ in range(n)]
    for d in range(n):
        p = parents[d]
        while p >= 0:  # d couples with each ancestor
            i, j = sorted((pos[d], pos[p]), reverse=True)
            nz[i][j] = True
            p = parents[p]
    for j in range(n):  # symbolic fill-in (none for a tree eliminated from the leaves)
        below = [i for i in range(j + 1, n) if nz[i][j]]
        for a_ in below:
            for b_ in below:
                if b_ > a_:
                    nz[b_][a_] = True
    return order, tuple(tuple(r) for r in nz)


__all__ = ["cho_solve", "cholesky", "spd_solve"]
