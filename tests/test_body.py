"""The MJCF body: planar kinematics and MJX dynamics against MuJoCo's C library."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx

from jaxgait.body.planar import load_body


@pytest.fixture(autouse=True)
def _float64():
    """Exact comparisons need float64; scoped to this module's tests."""
    with jax.enable_x64(True):
        yield


@pytest.fixture(scope="module")
def body():
    return load_body("fbl_planar")


def test_masses_and_lengths_from_the_mjcf(body):
    assert body.total_mass == pytest.approx(80.0)  # thesis Table 2.2 masses (errata: 80 kg)
    m = body.mj_model
    assert m.body("shank_r").pos[2] == pytest.approx(-0.5)
    assert m.body("foot_r").pos[2] == pytest.approx(-0.5)
    assert body.site_pos[body.site_id("ball_r"), 0] - body.site_pos[
        body.site_id("heel_r"), 0
    ] == pytest.approx(0.2)


def test_planar_kinematics_match_mujoco(body):
    m = body.mj_model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    ids = [body.site_id(n) for n in ("heel_r", "ball_r", "heel_l", "ball_l")]
    for _ in range(5):
        d.qpos[:] = rng.normal(size=m.nq) * 0.6
        d.qvel[:] = rng.normal(size=m.nv)
        mujoco.mj_forward(m, d)
        p, v = body.sites_and_velocities(jnp.asarray(d.qpos), jnp.asarray(d.qvel), ids)
        np.testing.assert_allclose(p, d.site_xpos[ids][:, [0, 2]], atol=1e-12)
        vel = np.zeros(6)
        for k, i in enumerate(ids):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, i, vel, 0)
            np.testing.assert_allclose(v[k], vel[[3, 5]], atol=1e-12)
        np.testing.assert_allclose(
            body.com(jnp.asarray(d.qpos)), d.subtree_com[0][[0, 2]], atol=1e-12
        )
        # J^T F by vjp equals MuJoCo's site Jacobian transpose
        jacp = np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jacp, None, ids[1])
        F = np.array([[0.0, 0.0], [3.0, -7.0], [0.0, 0.0], [0.0, 0.0]])
        q = body.site_forces_to_qfrc(jnp.asarray(d.qpos), jnp.asarray(F), ids)
        np.testing.assert_allclose(q, jacp[[0, 2]].T @ F[1], atol=1e-12)


def test_rejects_non_planar_model(tmp_path, monkeypatch):
    xml = """<mujoco><worldbody><body><joint type="hinge" axis="1 0 0"/>
    <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>"""
    (tmp_path / "bad.xml").write_text(xml)
    monkeypatch.setattr("jaxgait.body.planar.model_path", lambda name: tmp_path / "bad.xml")
    with pytest.raises(ValueError, match="not \\+-y"):
        load_body("bad")


def test_mjx_matches_mujoco_c(body):
    """MJX and MuJoCo's C step agree on this MJCF over 400 steps (joint torques, gravity)."""
    m = body.mj_model
    mx = mjx.put_model(m)
    d = mujoco.MjData(m)
    d.qpos[:] = [0.0, 0.3, 0.1, 0.3, 0.4, 0.1, -0.2, 0.2, -0.1]
    d.qvel[:] = [1.0, 0.0, 0.2, -1.0, 0.5, 0.0, 1.0, -0.5, 0.3]
    dx = mjx.put_data(m, d)
    step = jax.jit(lambda dx, f: mjx.step(mx, dx.replace(qfrc_applied=f)))
    for k in range(400):
        f = np.zeros(m.nv)
        f[3:] = 20.0 * np.sin(0.05 * k + np.arange(6))
        d.qfrc_applied[:] = f
        mujoco.mj_step(m, d)
        dx = step(dx, jnp.asarray(f))
    np.testing.assert_allclose(np.asarray(dx.qpos), d.qpos, atol=1e-8)
    np.testing.assert_allclose(np.asarray(dx.qvel), d.qvel, atol=1e-7)
