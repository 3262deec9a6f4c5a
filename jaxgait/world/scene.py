"""MJCF scenes for viewing: a body model standing on its environment's terrain.

Ground contact in jaxgait is computed from the :class:`~jaxgait.world.terrain.Terrain` height
function (:mod:`jaxgait.world.contact`), never from MuJoCo geoms.  A scene only shows that ground:
:func:`scene_xml` takes a body MJCF from the models folder (``fbl_planar`` or
``taga1991``), removes its flat ``plane`` floor and adds the terrain over [x0, x1] as a
height field sampled from the same height function (:func:`jaxgait.world.terrain.terrain_hfield`).
The terrain geom has ``contype = conaffinity = 0`` and no mass, so the scene's dynamics
(nq, nv, bodies, masses, inertias, options) are those of the plain body model.

The rendered surface at world x is the linear interpolation of h(x) between samples
``dx`` apart: exact at the samples, and off by at most |delta slope| * dx / 4 near a knot of
the profile that falls between two samples (1.25 mm for a 10 % slope change at
dx = 5 cm).

Viewing and replaying::

    python -m jaxgait.evaluate fbl_walk --env wavy --duration 10 \\
        --save-scene scene.xml --save-trajectory traj.csv
    python -m mujoco.viewer --mjcf scene.xml

``scene.xml`` holds the body in its MJCF pose; :func:`trajectory_qpos` turns the trajectory
CSV back into qpos rows for the scene (e.g. ``data.qpos[:] = row; mujoco.mj_forward(m, d)``
per frame, with :func:`mujoco.viewer.launch_passive` or :class:`mujoco.Renderer`).  The
scene has a ``follow`` camera (and a light) that track the walker from the side.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from jaxgait.core.resources import model_path
from jaxgait.world.terrain import Terrain, terrain_hfield

#: Height-field sample spacing along x [m].
DEFAULT_DX = 0.05
#: Geom group of the terrain (groups 0-2 are visible in MuJoCo's viewer by default).
TERRAIN_GROUP = 2
#: Name of the terrain geom and of its ``<hfield>`` asset.
TERRAIN_NAME = "terrain"
#: Largest number of height-field columns accepted (about 100 km at 5 cm).
MAX_COLUMNS = 2_000_000

_TRAJ_QPOS_COLUMNS = (
    "root_x_m",
    "root_z_m",
    "trunk_lean_deg",
    "hip_r_deg",
    "knee_r_deg",
    "ankle_r_deg",
    "hip_l_deg",
    "knee_l_deg",
    "ankle_l_deg",
)


def _as_terrain(terrain_or_env) -> Terrain:
    """The :class:`Terrain` of an :class:`~jaxgait.world.envs.Env`, or the terrain itself."""
    t = getattr(terrain_or_env, "terrain", terrain_or_env)
    if not isinstance(t, Terrain):
        raise TypeError(f"need a Terrain or an Env, got {type(terrain_or_env).__name__}")
    if np.ndim(t.xs) != 1:
        raise ValueError(f"need one terrain, got batched knots of shape {np.shape(t.xs)}")
    return t


def _fmt(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in np.ravel(v))


def scene_xml(
    terrain_or_env,
    x0: float,
    x1: float,
    *,
    model: str = "fbl_planar",
    dx: float = DEFAULT_DX,
    width: float = 2.0,
    base: float = 0.5,
    rgba=(0.7, 0.72, 0.68, 1.0),
) -> str:
    """MJCF text of the body ``model`` on the terrain over [x0, x1] (display only).

    Args:
      terrain_or_env: a :class:`~jaxgait.world.terrain.Terrain` or an
        :class:`~jaxgait.world.envs.Env`
        (its ``terrain``); one environment, not a batch.
      x0, x1: extent of the shown ground along x [m], x1 > x0.
      model: MJCF in the models folder (:func:`jaxgait.core.resources.model_path`).
      dx: largest sample spacing along x [m]; the samples are evenly spaced and include
        x0 and x1.
      width: extent of the ground along y [m].
      base: thickness of the solid below the lowest point of the surface [m].
      rgba: colour of the ground (tints its checker texture).

    Returns:
      The MJCF document as a string (loads with :func:`mujoco.MjModel.from_xml_string`).
      The ``<hfield name="terrain">`` has 2 rows (along y, equal) and ``ncol`` columns
      x0 + j (x1 - x0) / (ncol - 1); the geom ``terrain`` is in group
      :data:`TERRAIN_GROUP` with contype = conaffinity = 0.
    """
    terrain = _as_terrain(terrain_or_env)
    x0, x1 = float(x0), float(x1)
    if not (math.isfinite(x0) and math.isfinite(x1) and x1 > x0):
        raise ValueError(f"need finite x0 < x1, got x0={x0}, x1={x1}")
    if not (dx > 0 and width > 0 and base > 0):
        raise ValueError(f"dx, width and base must be > 0, got {dx}, {width}, {base}")
    ncol = max(2, math.ceil((x1 - x0) / dx - 1e-9) + 1)
    if ncol > MAX_COLUMNS:
        raise ValueError(f"{ncol} height-field columns for [{x0}, {x1}] at dx={dx}: too many")
    hf = terrain_hfield(terrain, x0, x1, ncol, width=width, base=base)

    path = model_path(model)
    root = ET.parse(path).getroot()
    world = root.find("worldbody")
    if world is None:
        raise ValueError(f"{path}: no <worldbody>")
    for g in world.findall("geom"):
        if g.get("type") == "plane":
            world.remove(g)

    asset = root.find("asset")
    if asset is None:
        asset = ET.Element("asset")
        root.insert(list(root).index(world), asset)
    ET.SubElement(
        asset,
        "hfield",
        name=TERRAIN_NAME,
        nrow=str(hf["nrow"]),
        ncol=str(hf["ncol"]),
        size=_fmt(hf["size"]),
        elevation=_fmt(hf["elevation"]),
    )
    # a checker pattern on the ground makes the walking speed visible
    ET.SubElement(
        asset,
        "texture",
        name=TERRAIN_NAME,
        type="2d",
        builtin="checker",
        rgb1="1 1 1",
        rgb2="0.85 0.85 0.85",
        width="256",
        height="256",
    )
    ET.SubElement(
        asset,
        "material",
        name=TERRAIN_NAME,
        texture=TERRAIN_NAME,
        texrepeat="1 1",
        texuniform="true",
    )
    geom = ET.Element(
        "geom",
        name=TERRAIN_NAME,
        type="hfield",
        hfield=TERRAIN_NAME,
        material=TERRAIN_NAME,
        pos=_fmt(hf["pos"]),
        contype="0",
        conaffinity="0",
        group=str(TERRAIN_GROUP),
        rgba=_fmt(rgba),
    )
    world.insert(0, geom)
    walker = world.find("body")
    if walker is not None:  # side camera and light that follow the walker's centre of mass
        ET.SubElement(
            walker, "camera", name="follow", mode="trackcom", pos="0 -4 0", xyaxes="1 0 0 0 0 1"
        )
        ET.SubElement(walker, "light", name="follow", mode="trackcom", pos="0 -3 3", dir="0 1 -1")
    # the free camera starts at the walker (MJCF x = 0), not at the middle of the ground
    cx = min(max(0.0, x0), x1)
    cz = float(np.asarray(terrain.height(np.asarray(cx, terrain.xs.dtype)))) + 0.9
    extent = 3.0
    ET.SubElement(root, "statistic", center=_fmt((cx, 0.0, cz)), extent=_fmt(extent))
    # far clipping plane (in units of extent) behind the whole ground
    zfar = max(50.0, 1.5 * (x1 - x0 + hf["size"][2]) / extent)
    visual = root.find("visual")
    if visual is None:
        visual = ET.SubElement(root, "visual")
    vmap = visual.find("map")
    if vmap is None:
        vmap = ET.SubElement(visual, "map")
    vmap.set("zfar", _fmt(zfar))
    root.insert(
        0,
        ET.Comment(
            f" jaxgait scene: {path.name} on the terrain over x = [{x0:g}, {x1:g}] m "
            f"({ncol} samples, dx = {(x1 - x0) / (ncol - 1):.4g} m); the terrain geom is "
            "display only, contact is computed by jaxgait from the same height function "
        ),
    )
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def write_scene(path, terrain_or_env, x0: float, x1: float, **kwargs) -> Path:
    """Write :func:`scene_xml` (same arguments) to ``path``; returns the path."""
    path = Path(path)
    path.write_text(scene_xml(terrain_or_env, x0, x1, **kwargs), encoding="utf-8")
    return path


def trajectory_qpos(traj: dict) -> np.ndarray:
    """(R, 9) qpos rows of ``models/fbl_planar.xml`` from a trajectory CSV.

    Args:
      traj: :func:`~jaxgait.analysis.trajectory_io.read_trajectory_csv` output (column -> (R,)
        array).

    Returns:
      (root_x, root_z, trunk_pitch, hip_r, knee_r, ankle_r, hip_l, knee_l, ankle_l) per row
      [m, rad], the MJCF joint order (:mod:`jaxgait.sim.trace`).
    """
    missing = [c for c in _TRAJ_QPOS_COLUMNS if c not in traj]
    if missing:
        raise KeyError(f"trajectory lacks columns {missing} (written by an older jaxgait?)")
    q = np.stack([np.asarray(traj[c], np.float64) for c in _TRAJ_QPOS_COLUMNS], -1)
    q[:, 2:] = np.deg2rad(q[:, 2:])
    return q
