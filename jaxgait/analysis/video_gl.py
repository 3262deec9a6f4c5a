"""The MuJoCo video backend: offscreen OpenGL rendering of the scene with its terrain.

The scene is :func:`jaxgait.world.scene.scene_xml`: the motion's MJCF body on the terrain as
a height field over the walked range, with the ``follow`` camera (side view tracking the
walker's centre of mass).  Per frame: ``qpos`` is set and ``mj_forward`` places the body;
each leg's ground reaction force is added to the scene as an arrow geom from its contact
point (0.5 m per body weight); the title and the time stamp are MuJoCo's text overlay.

The OpenGL context is made without a display: ``MUJOCO_GL=egl`` or ``osmesa`` picks one,
otherwise EGL is tried, then OSMesa.  EGL needs ``libegl1`` with a vendor library (Mesa's
``libegl-mesa0`` + ``libgl1-mesa-dri`` render on the CPU; a GPU driver's EGL works too);
OSMesa needs ``libosmesa6``.  PyOpenGL comes with MuJoCo's Python package.
"""

from __future__ import annotations

import importlib
import os

import mujoco
import numpy as np

from jaxgait.analysis.video_motion import Motion, VideoError, caption
from jaxgait.analysis.video_mpl import ARROW_M_PER_BW, contact_sites

#: GL backends tried without ``MUJOCO_GL``, in order.
GL_BACKENDS = ("egl", "osmesa")
_RGBA = ((0.85, 0.2, 0.15, 0.9), (0.15, 0.3, 0.8, 0.9))


def gl_context(width: int, height: int):
    """``(name, context)``: a current offscreen OpenGL context of MuJoCo's ``egl`` or
    ``osmesa`` module; :class:`VideoError` saying what was tried and why it failed."""
    want = os.environ.get("MUJOCO_GL", "").strip().lower()
    order = (want,) if want in GL_BACKENDS else GL_BACKENDS
    errors = []
    if want and want not in GL_BACKENDS:
        errors.append(f"MUJOCO_GL={want!r} is not an offscreen backend (egl or osmesa)")
        order = ()
    for name in order:
        try:
            mod = importlib.import_module(f"mujoco.{name}")
            ctx = mod.GLContext(width, height)
            ctx.make_current()
            return name, ctx
        except Exception as e:  # noqa: BLE001 - every failure means: backend unavailable
            errors.append(f"{name}: {type(e).__name__}: {e}".strip())
    raise VideoError(
        "no offscreen OpenGL backend (" + "; ".join(errors) + "); install the Debian "
        "packages libegl1 libgl1-mesa-dri (EGL) or libosmesa6 (OSMesa)"
    )


class GLFrames:
    """Frames of a :class:`~jaxgait.analysis.video.Motion` rendered by MuJoCo offscreen."""

    def __init__(self, motion: Motion, width: int, height: int):
        from jaxgait.world.scene import scene_xml
        from jaxgait.world.terrain import flat

        self.motion, self.w, self.h = motion, width, height
        x = motion.qpos[:, 0]
        terrain = motion.terrain if motion.terrain is not None else flat()
        xml = scene_xml(
            terrain, float(x.min()) - 4.0, float(x.max()) + 6.0, model=motion.model.split(".")[0]
        )
        m = self.model = mujoco.MjModel.from_xml_string(xml)
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), height)
        self.data = mujoco.MjData(m)
        self.gl_name, self.ctx = gl_context(width, height)
        try:
            small = width <= 640  # the overlay's text fits the frame
            scale = (
                mujoco.mjtFontScale.mjFONTSCALE_100
                if small
                else mujoco.mjtFontScale.mjFONTSCALE_150
            )
            self.con = mujoco.MjrContext(m, scale.value)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self.con)
        except Exception:
            self.ctx.free()
            raise
        self.scene = mujoco.MjvScene(m, maxgeom=2000)
        # shadows and reflections triple the cost of a frame on a software renderer
        self.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self.option = mujoco.MjvOption()
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.camera.fixedcamid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "follow")
        if self.camera.fixedcamid < 0:
            raise VideoError(f"the scene of {motion.model} has no 'follow' camera")
        self.viewport = mujoco.MjrRect(0, 0, width, height)
        self.feet = contact_sites(m)
        self.rgb = np.zeros((height, width, 3), np.uint8)

    def _arrow(self, k: int, start: np.ndarray, force: np.ndarray) -> None:
        scn = self.scene
        if scn.ngeom >= scn.maxgeom:
            return
        g = scn.geoms[scn.ngeom]
        z = np.zeros(3)
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, z, z, np.eye(3).ravel(), _RGBA[k])
        tip = start + np.array([force[0], 0.0, force[1]]) / self.motion.weight * ARROW_M_PER_BW
        mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, 0.02, start, tip)
        scn.ngeom += 1

    def render(self, row: int, t: float) -> np.ndarray:
        """(height, width, 3) uint8 frame of sample ``row`` labelled with time ``t``."""
        m, d, mo = self.model, self.data, self.motion
        d.qpos[:] = mo.qpos[row]
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        mujoco.mjv_updateScene(
            m, d, self.option, None, self.camera, mujoco.mjtCatBit.mjCAT_ALL.value, self.scene
        )
        if mo.grf is not None:
            for k, ids in enumerate(self.feet):
                f = mo.grf[row, k]
                if ids and np.hypot(*f) >= 0.01 * mo.weight:
                    start = d.site_xpos[ids].mean(0) - np.array([0.0, 0.15, 0.0])
                    self._arrow(k, start, f)
        mujoco.mjr_render(self.viewport, self.scene, self.con)
        left, right = caption(mo, row, t)
        mujoco.mjr_overlay(
            mujoco.mjtFont.mjFONT_NORMAL,
            mujoco.mjtGridPos.mjGRID_TOPLEFT,
            self.viewport,
            left or " ",
            right,
            self.con,
        )
        mujoco.mjr_readPixels(self.rgb, None, self.viewport, self.con)
        return np.flipud(self.rgb).copy()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.con.free()
        self.ctx.free()
        return False
