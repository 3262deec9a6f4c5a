"""MJCF scenes: the terrain height field matches the Terrain height function, dynamics unchanged."""

import json
import math
import os
import subprocess
import sys
import textwrap

import jax
import mujoco
import numpy as np
import pytest

from jaxgait.core.resources import model_path
from jaxgait.world import envs, scene
from jaxgait.world import terrain as T

#: Steep, short wavy course: 10 trapezoids at a 30 % grade from the first one on.
WAVY = T.WavyConfig(n_knots=64, n_structures=10, alpha_max=math.atan(0.3), n_increase=1)
#: Float32 terrain heights and hfield data, double-precision rays [m].
FLOAT_TOL = 5e-5


def _terrain(kind):
    if kind == "wavy":
        return T.wavy(jax.random.key(7), WAVY)
    if kind == "slope_down":
        return envs.make_env("slope_down", jax.random.PRNGKey(0))  # an Env works too
    return T.increasing_slope()


CASES = {  # kind: ground range [m]
    "wavy": (-3.0, 25.0),
    "slope_down": (-3.0, 12.0),
    "increasing_slope": (95.0, 140.0),  # far from the origin, 30 m above it
}


def _compile(xml):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d


def _ray_heights(m, d, xs, y=0.0):
    """Surface height [m] of the terrain geom straight below (x, y), by mj_ray."""
    groups = np.zeros(mujoco.mjNGROUP, np.uint8)
    groups[scene.TERRAIN_GROUP] = 1  # the terrain only, not the body
    top = 1000.0
    hit = np.zeros(1, np.int32)
    gid = m.geom(scene.TERRAIN_NAME).id
    z = np.empty(len(xs))
    for i, x in enumerate(xs):
        dist = mujoco.mj_ray(
            m, d, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), groups, 1, -1, hit
        )
        assert dist >= 0 and hit[0] == gid, (x, dist, hit[0])
        z[i] = top - dist
    return z


def _max_kink(terrain, x0, x1):
    """Largest slope change |s_{i} - s_{i-1}| at a knot inside (x0, x1)."""
    xs, zs = np.asarray(terrain.xs, np.float64), np.asarray(terrain.zs, np.float64)
    s = np.diff(zs) / np.diff(xs)
    inside = (xs[1:-1] > x0) & (xs[1:-1] < x1)
    return float(np.abs(np.diff(s))[inside].max(initial=0.0))


@pytest.mark.parametrize("kind", list(CASES))
def test_hfield_surface_is_terrain_height(kind):
    env_or_terrain = _terrain(kind)
    terrain = getattr(env_or_terrain, "terrain", env_or_terrain)
    x0, x1 = CASES[kind]
    m, d = _compile(scene.scene_xml(env_or_terrain, x0, x1, dx=0.05))
    ncol = int(m.hfield_ncol[0])
    dx = (x1 - x0) / (ncol - 1)
    assert dx <= 0.05 and m.hfield_nrow[0] == 2

    # between samples MuJoCo interpolates linearly: exact except near a knot that falls
    # between two samples, where the error is at most |slope change| * dx / 4
    xs = np.linspace(x0 + 1e-3, x1 - 1e-3, 3001)
    h = np.asarray(T._heights(terrain, xs.astype(terrain.xs.dtype)), np.float64)
    tol = _max_kink(terrain, x0, x1) * dx / 4 + FLOAT_TOL
    err = np.abs(_ray_heights(m, d, xs) - h)
    assert err.max() <= tol, (err.max(), tol)
    assert np.ptp(h) > 0.1  # the check is not trivially on flat ground

    # at the samples themselves the surface is the height function (any y across the strip)
    xj = x0 + dx * np.arange(1, ncol - 1, 7)
    hj = np.asarray(T._heights(terrain, xj.astype(terrain.xs.dtype)), np.float64)
    for y in (-0.9, 0.0, 0.9):
        np.testing.assert_allclose(_ray_heights(m, d, xj, y=y), hj, atol=FLOAT_TOL)


@pytest.mark.parametrize("model", ["fbl_planar", "taga1991"])
def test_scene_dynamics_unchanged(model):
    plain = mujoco.MjModel.from_xml_path(str(model_path(model)))
    m, _ = _compile(scene.scene_xml(T.wavy(jax.random.key(1), WAVY), -2.0, 10.0, model=model))
    assert (m.nq, m.nv, m.nu, m.nbody, m.njnt) == (
        plain.nq,
        plain.nv,
        plain.nu,
        plain.nbody,
        plain.njnt,
    )
    for field in ("body_mass", "body_inertia", "body_pos", "body_ipos", "jnt_axis", "jnt_type"):
        np.testing.assert_array_equal(getattr(m, field), getattr(plain, field), err_msg=field)
    np.testing.assert_array_equal(m.opt.gravity, plain.opt.gravity)
    assert m.opt.timestep == plain.opt.timestep and m.opt.disableflags == plain.opt.disableflags
    g = m.geom(scene.TERRAIN_NAME)
    assert g.type[0] == mujoco.mjtGeom.mjGEOM_HFIELD
    assert g.contype[0] == 0 and g.conaffinity[0] == 0 and g.group[0] == scene.TERRAIN_GROUP
    assert mujoco.mjtGeom.mjGEOM_PLANE not in set(m.geom_type)  # the flat floor is gone
    assert not np.any(m.geom_contype) and not np.any(m.geom_conaffinity)

    # same state and applied forces: same accelerations
    rng = np.random.default_rng(0)
    datas = [mujoco.MjData(x) for x in (plain, m)]
    qpos, qvel, frc = rng.normal(size=(3, plain.nq))
    for x, d in zip((plain, m), datas, strict=True):
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = qpos, qvel, frc
        mujoco.mj_forward(x, d)
    np.testing.assert_array_equal(datas[0].qacc, datas[1].qacc)


def test_scene_camera_and_inputs(tmp_path):
    terrain = T.slope(0.1, start=0.0)
    p = scene.write_scene(tmp_path / "s.xml", terrain, -1.0, 4.0)
    m = mujoco.MjModel.from_xml_path(str(p))
    assert m.cam("follow").mode[0] == mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM
    assert m.hfield_ncol[0] == 101  # 5 m at 5 cm, both ends included
    with pytest.raises(ValueError, match="x0 < x1"):
        scene.scene_xml(terrain, 2.0, 1.0)
    with pytest.raises(ValueError, match="batched"):
        scene.scene_xml(
            envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), 2)), 0, 1
        )
    with pytest.raises(TypeError):
        scene.scene_xml("flat", 0.0, 1.0)


_RENDER = textwrap.dedent(
    """
    import json, sys
    try:  # the OpenGL backend named by MUJOCO_GL is loaded on import or by the Renderer
        import mujoco
        m = mujoco.MjModel.from_xml_path(sys.argv[1])
        r = mujoco.Renderer(m, 65, 65)
    except Exception as e:
        print(json.dumps({"skip": repr(e)}))
        sys.exit(0)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    r.enable_depth_rendering()
    opt = mujoco.MjvOption()
    opt.geomgroup[:] = 0
    opt.geomgroup[int(sys.argv[2])] = 1
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.azimuth, cam.elevation, cam.distance = 90.0, -90.0, 5.0
    out = []
    for x in json.loads(sys.argv[3]):
        cam.lookat[:] = (x, 0.0, 0.0)
        r.update_scene(d, camera=cam, scene_option=opt)
        out.append(5.0 - float(r.render()[32, 32]))  # depth of the centre pixel, looking down
    r.close()
    print(json.dumps({"z": out}))
    """
)


def test_rendered_ground_height(tmp_path):
    """Depth image of the scene looking straight down: the drawn ground is at h(x)."""
    terrain = T.wavy(jax.random.key(7), WAVY)
    p = scene.write_scene(tmp_path / "w.xml", terrain, -3.0, 25.0)
    xs = [0.5, 3.1, 7.3, 12.9, 18.2, 22.0]
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    res = subprocess.run(
        [sys.executable, "-c", _RENDER, str(p), str(scene.TERRAIN_GROUP), json.dumps(xs)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    if "skip" in out:
        pytest.skip(f"no OpenGL rendering here: {out['skip']}")
    h = np.asarray(T._heights(terrain, np.asarray(xs, np.float32)), np.float64)
    assert np.ptp(h) > 0.1
    np.testing.assert_allclose(out["z"], h, atol=5e-3)  # depth buffer and grid resolution
