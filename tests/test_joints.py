"""Angle conventions and ligament soft limits (thesis eq. 2.38, Table 2.3)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.body.joints import SoftLimits, phi_to_q, q_to_phi, soft_limit_torque


@pytest.fixture(autouse=True)
def _float64():
    """Exact comparisons need float64; scoped to this module's tests."""
    with jax.enable_x64(True):
        yield


LIM = SoftLimits()


def test_conventions_round_trip_and_reference_posture():
    q = jnp.asarray([0.3, 0.2, -0.1])
    np.testing.assert_allclose(phi_to_q(q_to_phi(q)), q)
    # upright stance: hip and knee straight (180 deg), ankle neutral (90 deg)
    np.testing.assert_allclose(np.rad2deg(q_to_phi(jnp.zeros(3))), [180.0, 180.0, 90.0])
    # 10 deg of dorsiflexion is 80 deg in the Geyer convention
    assert float(np.rad2deg(q_to_phi(jnp.deg2rad(jnp.asarray([0, 0, 10.0])))[2])) == pytest.approx(
        80
    )


def test_no_torque_inside_range():
    phi = jnp.deg2rad(jnp.asarray([170.0, 150.0, 95.0]))
    assert np.all(np.asarray(soft_limit_torque(LIM, phi, jnp.ones(3))) == 0)


def test_hand_computed_upper_and_lower():
    # knee 5 deg past 175 deg, still extending at 0.5 deg/s: tau = -k d (1 + w/w_ref)
    d = np.deg2rad(5.0)
    w = np.deg2rad(0.5)
    tau = soft_limit_torque(
        LIM, jnp.asarray([np.pi, np.deg2rad(180.0), np.pi / 2]), jnp.asarray([0, w, 0])
    )
    assert float(tau[1]) == pytest.approx(-17.19 * d * (1 + w / 1.74e-2))
    # ankle 4 deg below 70 deg, moving further down at 0.2 deg/s: pushes back up
    d = np.deg2rad(4.0)
    w = np.deg2rad(-0.2)
    tau = soft_limit_torque(
        LIM, jnp.asarray([np.pi, np.pi, np.deg2rad(66.0)]), jnp.asarray([0, 0, w])
    )
    assert float(tau[2]) == pytest.approx(17.19 * d * (1 - w / 1.74e-2))


def test_no_torque_when_returning_faster_than_omega_ref():
    tau = soft_limit_torque(
        LIM, jnp.asarray([np.pi, np.deg2rad(180.0), np.pi / 2]), jnp.asarray([0, -0.05, 0])
    )
    assert float(tau[1]) == 0.0
