"""The matplotlib video backend: a stick figure of the body's geoms on the terrain profile.

The body is drawn from the MJCF model itself: MuJoCo's forward kinematics on the host
(``mujoco.mj_kinematics``) places every capsule geom, drawn as a line of the capsule's width,
and every sphere, drawn as a disc; geoms of bodies named ``*_r`` are the right leg (red,
in front), ``*_l`` the left leg (blue, behind).  So the planar body and Taga's share one
drawing, and a new MJCF body needs nothing here.  The ground is the terrain's exact
profile with a tick every 0.5 m (so the walking speed shows while the camera follows the
hip); each leg's ground reaction force is an arrow from its contact point (the middle of
heel and ball, or the ankle), 0.5 m per body weight.
"""

from __future__ import annotations

import mujoco
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch

from jaxgait.analysis.video_motion import Motion, caption
from jaxgait.core.resources import model_path

RIGHT, LEFT, TRUNK, GRF = "tab:red", "tab:blue", "0.2", "tab:green"
_CAPSULE, _SPHERE = int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_SPHERE)
#: Width of the view [m]; its height follows the frame's aspect ratio.
VIEW_WIDTH_M = 4.0
#: Ground shown below the terrain under the hip [m].
VIEW_BELOW_M = 0.25
#: GRF arrow length per body weight [m].
ARROW_M_PER_BW = 0.5
#: Spacing of the ground ticks [m].
TICK_M = 0.5


def _side(model: mujoco.MjModel, body: int) -> str:
    name = model.body(body).name
    return "r" if name.endswith("_r") else ("l" if name.endswith("_l") else "")


def contact_sites(model: mujoco.MjModel) -> list[list[int]]:
    """Per leg (right, left) the site ids whose mean is the leg's contact point: heel and
    ball when the body has feet, else the ankle."""
    names = {model.site(i).name: i for i in range(model.nsite)}
    out = []
    for s in ("r", "l"):
        ids = [names[n] for n in (f"heel_{s}", f"ball_{s}") if n in names]
        if not ids and f"ankle_{s}" in names:
            ids = [names[f"ankle_{s}"]]
        out.append(ids)
    return out


class BodyPoses:
    """Host forward kinematics of an MJCF body: capsule end points, sphere centres, feet."""

    def __init__(self, model_name: str):
        self.model = mujoco.MjModel.from_xml_path(str(model_path(model_name)))
        self.data = mujoco.MjData(self.model)
        m = self.model
        keep = [g for g in range(m.ngeom) if int(m.geom_type[g]) in (_CAPSULE, _SPHERE)]
        order = {"l": 0, "": 1, "r": 2}  # left behind, right in front
        self.geoms = sorted(keep, key=lambda g: order[_side(m, m.geom_bodyid[g])])
        self.sides = [_side(m, m.geom_bodyid[g]) for g in self.geoms]
        self.feet = contact_sites(m)

    def pose(self, qpos: np.ndarray):
        """``(segments {geom: ((x, z), (x, z))}, centres {geom: (x, z)}, feet (2, 2))``."""
        m, d = self.model, self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        seg, cen = {}, {}
        for g in self.geoms:
            p = d.geom_xpos[g]
            if int(m.geom_type[g]) == _CAPSULE:
                axis = d.geom_xmat[g].reshape(3, 3)[:, 2] * m.geom_size[g, 1]
                seg[g] = ((p - axis)[[0, 2]], (p + axis)[[0, 2]])
            else:
                cen[g] = p[[0, 2]]
        feet = np.zeros((2, 2))
        for k, ids in enumerate(self.feet):
            if ids:
                feet[k] = d.site_xpos[ids].mean(0)[[0, 2]]
        return seg, cen, feet


class StickFrames:
    """Frames of a :class:`~jaxgait.analysis.video.Motion` drawn by matplotlib (Agg)."""

    def __init__(self, motion: Motion, width: int, height: int):
        self.motion, self.w, self.h = motion, width, height
        self.body = BodyPoses(motion.model)
        dpi = 100.0
        self.fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.ax = self.fig.add_axes((0, 0, 1, 1))
        ax.set_axis_off()
        ax.set_aspect("equal")
        self.view_h = VIEW_WIDTH_M * height / width
        self.px_per_m = width / VIEW_WIDTH_M
        x = motion.qpos[:, 0]
        self.ground = self._ground(float(x.min()) - VIEW_WIDTH_M, float(x.max()) + VIEW_WIDTH_M)
        g = self.ground
        ax.fill_between(g[:, 0], g[:, 1], g[:, 1].min() - 5.0, color="0.88", lw=0, zorder=0)
        ax.plot(g[:, 0], g[:, 1], color="0.35", lw=1.2, zorder=1)
        ticks = np.arange(np.ceil(g[0, 0] / TICK_M), np.floor(g[-1, 0] / TICK_M) + 1) * TICK_M
        tz = np.interp(ticks, g[:, 0], g[:, 1])
        for xt, zt in zip(ticks, tz, strict=True):
            ax.plot([xt, xt], [zt, zt - 0.06], color="0.35", lw=1.0, zorder=1)
        pts_per_m = self.px_per_m * 72.0 / dpi
        m = self.body.model
        self.lines, self.discs = {}, {}
        for g_id, side in zip(self.body.geoms, self.body.sides, strict=True):
            col = RIGHT if side == "r" else (LEFT if side == "l" else TRUNK)
            z = {"l": 2, "": 3, "r": 4}[side]
            r = float(m.geom_size[g_id, 0])
            if int(m.geom_type[g_id]) == _CAPSULE:
                (ln,) = ax.plot([], [], color=col, lw=max(1.0, 2 * r * pts_per_m), zorder=z)
                ln.set_solid_capstyle("round")
                self.lines[g_id] = ln
            else:
                self.discs[g_id] = ax.add_patch(Circle((0, 0), r, color=col, zorder=z))
        self.arrows = []
        for alpha in (0.9, 0.55):  # right, left
            a = FancyArrowPatch(
                (0, 0), (0, 0), arrowstyle="-|>", mutation_scale=14, color=GRF, lw=2.5, zorder=6
            )
            a.set_alpha(alpha)
            self.arrows.append(ax.add_patch(a))
        style = dict(transform=ax.transAxes, fontsize=9, family="monospace", va="top")
        self.title = ax.text(0.01, 0.98, motion.title, ha="left", **style)
        self.clock = ax.text(0.99, 0.98, "", ha="right", **style)
        if motion.grf is not None:
            note = f"GRF arrows: {ARROW_M_PER_BW:g} m per body weight (right leg darker)"
            ax.text(0.01, 0.02, note, ha="left", color=GRF, **{**style, "va": "bottom"})

    def _ground(self, x0: float, x1: float) -> np.ndarray:
        terrain = self.motion.terrain
        if terrain is None:
            return np.array([[x0, 0.0], [x1, 0.0]])
        from jaxgait.world.terrain import terrain_polyline

        return terrain_polyline(terrain, x0, x1)

    def render(self, row: int, t: float) -> np.ndarray:
        """(height, width, 3) uint8 frame of sample ``row`` labelled with time ``t``."""
        mo = self.motion
        q = mo.qpos[row]
        seg, cen, feet = self.body.pose(q)
        for g, ln in self.lines.items():
            a, b = seg[g]
            ln.set_data([a[0], b[0]], [a[1], b[1]])
        for g, disc in self.discs.items():
            disc.center = tuple(cen[g])
        for k, arrow in enumerate(self.arrows):
            f = np.zeros(2) if mo.grf is None else mo.grf[row, k]
            if np.hypot(*f) < 0.01 * mo.weight:
                arrow.set_visible(False)
                continue
            arrow.set_visible(True)
            tip = feet[k] + f / mo.weight * ARROW_M_PER_BW
            arrow.set_positions(tuple(feet[k]), tuple(tip))
        xc = float(q[0])
        zg = float(np.interp(xc, self.ground[:, 0], self.ground[:, 1]))
        self.ax.set_xlim(xc - VIEW_WIDTH_M / 2, xc + VIEW_WIDTH_M / 2)
        self.ax.set_ylim(zg - VIEW_BELOW_M, zg - VIEW_BELOW_M + self.view_h)
        left, right = caption(mo, row, t)
        self.title.set_text(left)
        self.clock.set_text(right)
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.fig.clear()
        return False
