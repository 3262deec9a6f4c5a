"""Unrolled small SPD solves and the implicit row system against dense NumPy solves."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait.core.linalg import cho_solve, cholesky, spd_solve
from jaxgait.sim.rows import implicit_row_velocities


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def _spd(rng, n, cond=1e3):
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (q * np.geomspace(1.0, cond, n)) @ q.T


@settings(max_examples=15, deadline=None)
@given(n=st.integers(1, 9), seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_cholesky_and_solve_match_numpy(n, seed, k):
    rng = np.random.default_rng(seed)
    a = _spd(rng, n)
    b = rng.normal(size=(n, k))
    L = np.asarray(cholesky(jnp.asarray(a)))
    np.testing.assert_allclose(L, np.linalg.cholesky(a), rtol=1e-9, atol=1e-9)
    assert np.all(np.triu(L, 1) == 0)
    np.testing.assert_allclose(
        np.asarray(cho_solve(jnp.asarray(L), jnp.asarray(b))),
        np.linalg.solve(a, b),
        rtol=1e-8,
        atol=1e-8,
    )
    np.testing.assert_allclose(
        np.asarray(spd_solve(jnp.asarray(a), jnp.asarray(b[:, 0]))),
        np.linalg.solve(a, b[:, 0]),
        rtol=1e-8,
        atol=1e-8,
    )


def test_solve_under_vmap_and_bad_shapes():
    rng = np.random.default_rng(0)
    a = np.stack([_spd(rng, 5) for _ in range(7)])
    b = rng.normal(size=(7, 5))
    x = jax.vmap(spd_solve)(jnp.asarray(a), jnp.asarray(b))
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(a, b[..., None])[..., 0], rtol=1e-8)
    with pytest.raises(ValueError, match="square"):
        cholesky(jnp.zeros((3, 4)))
    with pytest.raises(ValueError, match="rows"):
        cho_solve(jnp.eye(3), jnp.zeros(4))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), zeros=st.integers(0, 14))
def test_implicit_rows_match_the_dense_backward_euler_system(seed, zeros):
    """y = J v+ with v+ from the dual row system (I + dt A C) y = J v + dt J M^-1 f + dt A a,
    A = J M^-1 J^T (the same backward-Euler step), also with undamped rows (c = 0)."""
    rng = np.random.default_rng(seed)
    nv, R, dt = 9, 14, 5e-4
    M = _spd(rng, nv, cond=1e2) * 5.0
    minv = np.linalg.inv(M)
    J = rng.normal(size=(R, nv))
    c = rng.uniform(0, 3e4, size=R)
    c[rng.permutation(R)[:zeros]] = 0.0
    a, v, f = rng.normal(size=R) * 100, rng.normal(size=nv), rng.normal(size=nv) * 50
    A = J @ minv @ J.T
    want = np.linalg.solve(np.eye(R) + dt * A * c[None, :], J @ v + dt * J @ minv @ f + dt * A @ a)
    y = implicit_row_velocities(*map(jnp.asarray, (J, a, c, M, v, f)), dt)
    np.testing.assert_allclose(np.asarray(y), want, rtol=1e-7, atol=1e-9)


def test_mass_and_forces_give_the_mjx_forward_acceleration(fbl_model):
    """M^-1 (qfrc_applied + passive - bias) from the step's MJX passes = mjx.forward's qacc."""
    from mujoco import mjx

    rng = np.random.default_rng(3)
    for _ in range(3):
        q = jnp.asarray(rng.normal(size=9) * 0.5).at[1].set(1.0)
        v, f = jnp.asarray(rng.normal(size=9)), jnp.asarray(rng.normal(size=9) * 50)
        M, smooth = fbl_model.mass_and_forces(q, v, f)
        d = fbl_model._template.replace(qpos=q, qvel=v, qfrc_applied=f)
        want = mjx.forward(fbl_model.mjx_model, d).qacc
        np.testing.assert_allclose(np.asarray(spd_solve(M, smooth)), np.asarray(want), atol=1e-9)


def _tree_pattern(parents):
    """Boolean (n, n): i == j or one of the two is an ancestor of the other."""
    n = len(parents)
    pat = np.eye(n, dtype=bool)
    for d in range(n):
        p = parents[d]
        while p >= 0:
            pat[d, p] = pat[p, d] = True
            p = parents[p]
    return pat


@settings(max_examples=25, deadline=None)
@given(data=st.data(), n=st.integers(1, 10), seed=st.integers(0, 2**31 - 1))
def test_tree_solve_matches_numpy_and_reads_only_the_tree(data, n, seed):
    """SPD matrices with the sparsity of a random kinematic tree (sums of outer products of
    vectors on one chain, as M and J^T C J): the tree-structured solve equals the dense one,
    and entries outside the tree's pattern are never read."""
    parents = tuple(data.draw(st.integers(-1, i - 1)) for i in range(n))
    rng = np.random.default_rng(seed)
    pat = _tree_pattern(parents)
    a = np.eye(n)
    for d in range(n):  # a vector on the chain from d to its root
        chain = pat[d] & (np.arange(n) <= d)
        u = rng.normal(size=n) * chain
        a += np.outer(u, u) * rng.uniform(0.1, 10.0)
    assert np.all(a[~pat] == 0)
    b = rng.normal(size=(n, 2))
    x = np.asarray(spd_solve(jnp.asarray(a), jnp.asarray(b), parents))
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-8, atol=1e-10)
    garbage = np.where(pat, a, rng.normal(size=(n, n)) * 1e3)
    np.testing.assert_array_equal(
        np.asarray(spd_solve(jnp.asarray(garbage), jnp.asarray(b), parents)), x
    )


def test_tree_solve_rejects_bad_trees():
    with pytest.raises(ValueError, match="parents"):
        spd_solve(jnp.eye(3), jnp.ones(3), (-1, 0))
    with pytest.raises(ValueError, match="parents"):
        spd_solve(jnp.eye(3), jnp.ones(3), (-1, 2, 0))


def test_step_systems_have_the_tree_sparsity(fbl_model):
    """M from MJX and the contact rows' J^T J couple only dofs on one chain of the body's
    tree, so the step may use the tree-structured solve."""
    pat = _tree_pattern(fbl_model.dof_parents)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = jnp.asarray(rng.normal(size=9) * 0.5).at[1].set(1.0)
        M, _ = fbl_model.mass_and_forces(q, jnp.zeros(9), jnp.zeros(9))
        assert np.all(np.asarray(M)[~pat] == 0)
        _, jac = fbl_model.points_jacobian(q, jnp.zeros(()))
        for p in range(4):  # heel and ball of each foot, both directions
            J = np.asarray(jac[p])
            assert np.all((J.T @ J)[~pat] == 0)
