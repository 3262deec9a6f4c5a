"""Trajectory CSV files: one row per logged sample of a rollout, alive samples only.

The file starts with a block of ``# `` comment lines (format name, body mass, number of
rows and the column list below), then one header line with the column names, then the data,
comma-separated. Columns, in order:

=====================  ======  ===============================================================
``time_s``             s       simulated time of the sample
``hip_r_deg``          deg     right hip flexion +: thigh relative to the trunk (not to the
                               vertical), 0 = thigh along the trunk axis
``knee_r_deg``         deg     right knee flexion + (0 = straight)
``ankle_r_deg``        deg     right ankle dorsiflexion + (0 = foot perpendicular to shank)
``hip_l_deg``          deg     left hip flexion +, thigh relative to the trunk
``knee_l_deg``         deg     left knee flexion +
``ankle_l_deg``        deg     left ankle dorsiflexion +
``trunk_lean_deg``     deg     trunk pitch from the vertical, forward lean +
``com_x_m``            m       whole-body centre of mass, forward position
``com_z_m``            m       whole-body centre of mass, height above z = 0 (not above the
                               local ground on sloped or wavy terrain)
``com_vx_mps``         m/s     forward velocity of the centre of mass
``grf_z_r_bw``         BW      vertical ground reaction force on the right foot (heel + ball),
                               in body weights: N / (mass * 9.81 m/s^2)
``grf_z_l_bw``         BW      the same, left foot
``grf_x_r_bw``         BW      horizontal (forward +) ground reaction force, right foot
``grf_x_l_bw``         BW      the same, left foot
``stance_r``           0/1     right leg in stance (filtered ground contact of the controller)
``stance_l``           0/1     left leg in stance
``act_<M>_r``          0..1    activation of muscle M of the right leg, for every muscle of
                               the model in table order (FBL: HFL, GLU, HAM, VAS, GAS, SOL, TA)
``act_<M>_l``          0..1    the same muscles, left leg
``energy_J``           J       cumulative metabolic energy since the start
``root_x_m``           m       MJCF root slide joint ``root_x`` (qpos[0]): forward
                               displacement of the trunk body (hip) from its MJCF position
``root_z_m``           m       MJCF root slide joint ``root_z`` (qpos[1]): vertical
                               displacement of the hip from its MJCF position (z = 1 m in
                               ``models/fbl_planar.xml``)
=====================  ======  ===============================================================

Joint angles follow the Winter convention of :mod:`jaxgait.sim.trace` (flexion and
dorsiflexion positive), so they compare directly with :mod:`jaxgait.analysis.refdata`.  They are
also the MJCF joint coordinates: ``root_x_m``, ``root_z_m``, then ``trunk_lean_deg``,
``hip_r_deg`` ... ``ankle_l_deg`` in radians are the model's qpos, so a file replays in the
MJCF scene of :mod:`jaxgait.world.scene` (:func:`jaxgait.world.scene.trajectory_qpos`).  The root
columns come last so that the earlier columns keep their positions.

:func:`write_trajectory_csv` writes atomically (temporary file in the same folder, then
rename); :func:`read_trajectory_csv` reads a file back into a dict of arrays.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from jaxgait.muscles.mtu import MUSCLES

#: Gravitational acceleration used for body weights [m/s^2].
G = 9.81
#: Format tag written on the first line of every file.
FORMAT = "jaxgait trajectory v1"

_FIXED_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("time_s", "s", "simulated time"),
    ("hip_r_deg", "deg", "right hip flexion +, thigh relative to the trunk"),
    ("knee_r_deg", "deg", "right knee flexion +"),
    ("ankle_r_deg", "deg", "right ankle dorsiflexion +"),
    ("hip_l_deg", "deg", "left hip flexion +, thigh relative to the trunk"),
    ("knee_l_deg", "deg", "left knee flexion +"),
    ("ankle_l_deg", "deg", "left ankle dorsiflexion +"),
    ("trunk_lean_deg", "deg", "trunk pitch from vertical, forward lean +"),
    ("com_x_m", "m", "centre of mass, forward position"),
    ("com_z_m", "m", "centre of mass, height above z = 0"),
    ("com_vx_mps", "m/s", "centre of mass, forward velocity"),
    ("grf_z_r_bw", "BW", "vertical GRF, right foot, N / (mass * 9.81)"),
    ("grf_z_l_bw", "BW", "vertical GRF, left foot"),
    ("grf_x_r_bw", "BW", "horizontal GRF (forward +), right foot"),
    ("grf_x_l_bw", "BW", "horizontal GRF (forward +), left foot"),
    ("stance_r", "0/1", "right leg in stance"),
    ("stance_l", "0/1", "left leg in stance"),
)
_BOOL_COLUMNS = ("stance_r", "stance_l")


def trajectory_columns(muscle_names=MUSCLES) -> list[tuple[str, str, str]]:
    """(name, unit, description) of every column, in file order, for these muscles."""
    cols = list(_FIXED_COLUMNS)
    for side, leg in (("r", "right"), ("l", "left")):
        for m in muscle_names:
            cols.append((f"act_{m}_{side}", "0..1", f"activation of {m}, {leg} leg"))
    cols.append(("energy_J", "J", "cumulative metabolic energy"))
    cols.append(("root_x_m", "m", "qpos[0], root_x: forward displacement of the hip"))
    cols.append(("root_z_m", "m", "qpos[1], root_z: vertical displacement of the hip"))
    return cols


def _muscle_names(model, n: int) -> tuple[str, ...]:
    names = getattr(getattr(model, "muscles", None), "names", None)
    names = tuple(names) if names is not None else MUSCLES
    if len(names) != n:
        raise ValueError(f"trace has {n} muscles per leg but the model names {len(names)}")
    return names


def trajectory_table(trace, summary=None, model=None) -> tuple[list[str], np.ndarray]:
    """Column names and the (R, C) float64 table of the alive rows of ``trace``.

    The body mass for the force columns comes from ``summary.mass`` if given, else
    ``model.mass``.
    """
    alive = np.asarray(trace.alive, bool).reshape(-1)
    if summary is not None:
        mass = float(np.asarray(summary.mass))
    elif model is not None:
        mass = float(model.mass)
    else:
        raise ValueError("need summary or model for the body mass")
    if not mass > 0:
        raise ValueError(f"body mass must be > 0, got {mass}")
    bw = mass * G
    q = np.asarray(trace.qpos, np.float64)[alive]
    grf = np.asarray(trace.grf, np.float64)[alive]
    act = np.asarray(trace.act, np.float64)[alive]
    names = _muscle_names(model, np.asarray(trace.act).shape[-1])
    stance = np.asarray(trace.stance, bool)[alive]
    parts = [
        np.asarray(trace.t, np.float64)[alive][:, None],
        np.rad2deg(q[:, 3:9]),
        np.rad2deg(q[:, 2:3]),
        np.asarray(trace.com, np.float64)[alive],
        np.asarray(trace.com_vel, np.float64)[alive][:, :1],
        grf[:, :, 1] / bw,
        grf[:, :, 0] / bw,
        stance.astype(np.float64),
        act[:, 0, :],
        act[:, 1, :],
        np.asarray(trace.energy, np.float64)[alive][:, None],
        q[:, 0:2],
    ]
    cols = [c[0] for c in trajectory_columns(names)]
    data = np.concatenate([p.reshape(len(q), -1) for p in parts], axis=1)
    assert data.shape[1] == len(cols)
    return cols, data


def write_trajectory_csv(path, trace, summary=None, model=None) -> Path:
    """Write the alive rows of a rollout to ``path`` (columns: see the module docstring).

    Args:
      path: output file (its folder must exist); replaced atomically.
      trace: a single rollout's :class:`~jaxgait.sim.trace.Trace` (no batch axis).
      summary: its :class:`~jaxgait.sim.trace.Summary` (body mass for the BW columns).
      model: the :class:`~jaxgait.sim.Model` (muscle names; mass if no summary).

    Returns:
      The path written.
    """
    path = Path(path)
    cols, data = trajectory_table(trace, summary, model)
    names = _muscle_names(model, np.asarray(trace.act).shape[-1])
    mass = float(np.asarray(summary.mass)) if summary is not None else float(model.mass)
    header = [
        FORMAT,
        f"model: {getattr(model, 'name', 'unknown')}",
        f"mass_kg: {mass:.6g}",
        f"rows: {data.shape[0]} (alive samples only)",
        "columns (name [unit] description):",
    ]
    header += [f"  {n} [{u}] {d}" for n, u, d in trajectory_columns(names)]
    fmt = ["%d" if c in _BOOL_COLUMNS else "%.9g" for c in cols]
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            for line in header:
                f.write(f"# {line}\n")
            f.write(",".join(cols) + "\n")
            if data.size:
                np.savetxt(f, data, fmt=fmt, delimiter=",")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_trajectory_csv(path) -> dict[str, np.ndarray]:
    """Read a file written by :func:`write_trajectory_csv`.

    Returns:
      Column name -> (R,) array in file order: float64, except ``stance_r`` / ``stance_l``
      which are bool.
    """
    path = Path(path)
    with open(path, encoding="utf-8") as f:
        lines = [ln for ln in f if ln.strip() and not ln.startswith("#")]
    if not lines:
        raise ValueError(f"{path}: no header line (not a trajectory CSV)")
    cols = [c.strip() for c in lines[0].split(",")]
    rows = []
    for i, ln in enumerate(lines[1:], start=1):
        cells = ln.split(",")
        if len(cells) != len(cols):
            raise ValueError(f"{path}: data row {i} has {len(cells)} cells, header {len(cols)}")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            raise ValueError(f"{path}: data row {i} has a non-numeric cell") from None
    data = np.asarray(rows, np.float64).reshape(len(rows), len(cols))
    out = {}
    for j, c in enumerate(cols):
        out[c] = data[:, j] > 0.5 if c in _BOOL_COLUMNS else data[:, j]
    return out
