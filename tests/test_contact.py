"""Geyer ground contact and the implicit row solver."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.sim.rows import implicit_row_velocities
from jaxgait.world import terrain
from jaxgait.world.contact import (
    ContactParams,
    contact_finalize,
    contact_forces,
    contact_rows,
    init_contact,
)


@pytest.fixture(autouse=True)
def _float64():
    """Exact comparisons need float64; scoped to this module's tests."""
    with jax.enable_x64(True):
        yield


CP = ContactParams()


def _one(pos, vel, state=None, ter=None):
    ter = terrain.flat(dtype=jnp.float64) if ter is None else ter
    pos = jnp.asarray([pos], jnp.float64)
    vel = jnp.asarray([vel], jnp.float64)
    state = init_contact(pos) if state is None else state
    return contact_forces(CP, ter, state, pos, vel)


def test_no_force_above_ground():
    f, st, fn = _one([0.3, 0.001], [0.5, -1.0])
    assert np.all(np.asarray(f) == 0.0) and float(fn[0]) == 0.0
    assert not bool(st.sliding[0])


def test_normal_force_hand_computed():
    # 2 mm penetration, moving down at 0.03 m/s: F = k d (1 - v/vmax) = 78480 * 0.002 * 2
    f, _, fn = _one([0.0, -0.002], [0.0, -0.03])
    assert float(fn[0]) == pytest.approx(78480 * 0.002 * 2.0)
    # moving up at v_max or faster: no force (Geyer's (u2 < 1) gate)
    _, _, fn = _one([0.0, -0.002], [0.0, 0.04])
    assert float(fn[0]) == 0.0


def test_stick_slip_stick():
    ter = terrain.flat(dtype=jnp.float64)
    anchor = jnp.asarray([[0.0, 0.0]])
    st = init_contact(anchor)
    # 1 cm from the anchor under 157 N of normal load: k_t s = 78.5 N < 0.9 * 157 -> sticks
    f, st1, fn = contact_forces(CP, ter, st, jnp.asarray([[0.01, -0.002]]), jnp.zeros((1, 2)))
    assert not bool(st1.sliding[0])
    assert float(f[0, 0]) == pytest.approx(-7848 * 0.01)
    np.testing.assert_allclose(st1.anchor, anchor)  # anchor held while sticking
    # 3 cm: 235 N > 0.9 * 157 N -> slides, friction capped at mu_slide F_n against the spring
    f, st2, fn = contact_forces(CP, ter, st, jnp.asarray([[0.03, -0.002]]), jnp.zeros((1, 2)))
    assert bool(st2.sliding[0])
    assert float(f[0, 0]) == pytest.approx(-0.8 * float(fn[0]))
    # sliding fast: keeps sliding, friction opposes the motion, anchor follows the point
    f, st3, fn = contact_forces(
        CP, ter, st2, jnp.asarray([[0.05, -0.002]]), jnp.asarray([[0.5, 0.0]])
    )
    assert bool(st3.sliding[0])
    assert float(f[0, 0]) == pytest.approx(-0.8 * float(fn[0]))
    assert float(st3.anchor[0, 0]) == pytest.approx(0.05)
    # nearly stopped (< v_limit): sticks again where it is
    f, st4, _ = contact_forces(
        CP, ter, st3, jnp.asarray([[0.05, -0.002]]), jnp.asarray([[0.005, 0.0]])
    )
    assert not bool(st4.sliding[0])
    assert float(st4.anchor[0, 0]) == pytest.approx(0.05)


@pytest.mark.parametrize("grade", [0.1, -0.2])
def test_force_along_the_slope_normal(grade):
    ter = terrain.slope(grade, start=-5.0, dtype=jnp.float64)
    x = 1.0
    h = float(ter.height(jnp.asarray(x)))
    n = np.array([-grade, 1.0]) / np.hypot(grade, 1.0)
    pos = np.array([x, h]) - 0.003 * n  # 3 mm below the surface, along the normal
    f, _, fn = _one(pos, [0.0, 0.0], ter=ter)
    assert float(fn[0]) == pytest.approx(78480 * 0.003, rel=1e-6)
    np.testing.assert_allclose(np.asarray(f[0]) / float(fn[0]), n, atol=1e-9)


def test_implicit_rows_single_mass_matches_backward_euler():
    # one row on a 0.2 kg point: (1 + dt c / m) y = v + dt (g + a / m)
    m, dt, c, a, v, g = 0.2, 5e-4, 2.0e4, 50.0, -1.0, -9.81
    J = jnp.ones((1, 1))
    y = implicit_row_velocities(
        J,
        jnp.asarray([a]),
        jnp.asarray([c]),
        jnp.asarray([[m]]),
        jnp.asarray([v]),
        jnp.asarray([m * g]),
        dt,
    )
    assert float(y[0]) == pytest.approx((v + dt * (g + a / m)) / (1 + dt * c / m))


def test_implicit_damping_is_stable_where_explicit_is_not():
    # A 0.2 kg point pressed 5 mm into the ground: explicit damping c dt / m = 33 blows up.
    m, dt = 0.2, 5e-4
    ter = terrain.flat(dtype=jnp.float64)
    z, vz = -0.005, -0.5
    st = init_contact(jnp.asarray([[0.0, z]]))
    for _ in range(400):
        pos = jnp.asarray([[0.0, z]])
        vel = jnp.asarray([[0.0, vz]])
        rows = contact_rows(CP, ter, st, pos, vel)
        y = implicit_row_velocities(
            jnp.ones((1, 1)),
            rows.a_n,
            rows.c_n,
            jnp.asarray([[m]]),
            jnp.asarray([vz]),
            jnp.asarray([-9.81 * m]),
            dt,
        )
        _, st, fn = contact_finalize(CP, rows, st, pos, y, jnp.zeros(1))
        vz = vz + dt * (-9.81 + float(fn[0]) / m)
        z = z + dt * vz
        assert abs(vz) < 1.0
    # settles at static penetration m g / k
    assert z == pytest.approx(-0.2 * 9.81 / 78480, abs=2e-5)
