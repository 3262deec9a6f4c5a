"""Human reference gait curves (joint angles, ground reaction force, EMG) as NumPy arrays.

Every curve spans one gait cycle of the reference (right) leg: ``gait_cycle_pct`` 0 is its
heel strike, 100 its next heel strike. Angles are in degrees with hip flexion, knee flexion
and ankle dorsiflexion positive (the convention of :mod:`jaxgait.sim.trace`); forces are in body
weights (1 BW = m g); EMG envelopes are unitless in [0, 1]. The files and their provenance
are described in ``jaxgait/data/SOURCES.md``.

Loaders are cached and return frozen dataclasses whose arrays are read-only, so the same
object can be shared and closed over by jitted code. A missing or malformed file raises an
error that names the file, and the column or row at fault.
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxgait.core.resources import data_dir as _default_data_dir

WINTER_KINEMATICS_FILE = "winter_normal_walking_kinematics.csv"
WINTER_GRF_FILE = "winter_normal_walking_grf.csv"
WALK_EMG_FILE = "rajagopal2016_walk_1subject_emg_right.csv"
RUN_KINEMATICS_FILE = "fukuchi2017_running_3p5ms_3subjects_kinematics.csv"
RUN_GRF_FILE = "fukuchi2017_running_3p5ms_3subjects_grf.csv"
RUN_EMG_FILE = "rajagopal2016_run_1subject_emg_right.csv"

#: Model muscles that have a human EMG reference, in this order in :class:`Emg`.
EMG_MUSCLES = ("GLU", "HAM", "VAS", "GAS", "SOL", "TA", "RF")

# Model muscle -> source columns averaged to form its envelope.
_WALK_EMG_COLUMNS = {
    "GLU": ("gluteus_maximus",),
    "HAM": ("medial_hamstrings", "biceps_femoris"),
    "VAS": ("vastus_lateralis", "vastus_medius"),
    "GAS": ("gastrocnemius",),
    "SOL": ("soleus",),
    "TA": ("tibialis_anterior",),
    "RF": ("rectus_femoris",),
}
_RUN_EMG_COLUMNS = {
    "GLU": ("GMAX",),
    "HAM": ("SM", "BFLH"),
    "VAS": ("VL", "VM"),
    "GAS": ("GASLAT", "GASMED"),
    "SOL": ("SOL",),
    "TA": ("TA",),
    "RF": ("RF",),
}
_RUN_EMG_SUFFIX = "_norm_to_trial_max"


class RefDataError(ValueError):
    """A reference data file is malformed (missing column, bad number, bad cycle axis)."""


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Sagittal joint angles over one gait cycle, mean and SD across subjects.

    Attributes:
      gait_cycle_pct: (N,) percent of the gait cycle, strictly increasing in [0, 100].
      hip_mean_deg, knee_mean_deg, ankle_mean_deg: (N,) mean angle [deg]; hip flexion +,
        knee flexion +, ankle dorsiflexion +.
      hip_sd_deg, knee_sd_deg, ankle_sd_deg: (N,) standard deviation [deg].
      sd_is_floor: (N, 3) bool, the SD of (hip, knee, ankle) is a floor value rather than a
        measured SD (Winter data; all False when the source has no floor).
      speed_mps: walking/running speed of the reference [m/s].
      source: data file name.
    """

    gait_cycle_pct: np.ndarray
    hip_mean_deg: np.ndarray
    hip_sd_deg: np.ndarray
    knee_mean_deg: np.ndarray
    knee_sd_deg: np.ndarray
    ankle_mean_deg: np.ndarray
    ankle_sd_deg: np.ndarray
    sd_is_floor: np.ndarray
    speed_mps: float
    source: str

    @property
    def n_samples(self) -> int:
        return int(self.gait_cycle_pct.shape[0])

    @property
    def mean_deg(self) -> np.ndarray:
        """(N, 3) mean angles [deg], columns (hip, knee, ankle)."""
        return np.stack([self.hip_mean_deg, self.knee_mean_deg, self.ankle_mean_deg], axis=1)

    @property
    def sd_deg(self) -> np.ndarray:
        """(N, 3) SD [deg], columns (hip, knee, ankle)."""
        return np.stack([self.hip_sd_deg, self.knee_sd_deg, self.ankle_sd_deg], axis=1)


@dataclass(frozen=True, eq=False)
class VerticalGRF:
    """Ground reaction force of the reference leg over one gait cycle.

    Attributes:
      gait_cycle_pct: (N,) percent of the gait cycle.
      mean_bw: (N,) mean vertical GRF [BW], upward +.
      sd_bw: (N,) SD of the vertical GRF [BW].
      sd_is_floor: (N,) bool, the SD is a floor value (Winter data; else all False).
      ap_mean_bw: (N,) mean anterior-posterior GRF [BW], propulsive +.
      source: data file name.
    """

    gait_cycle_pct: np.ndarray
    mean_bw: np.ndarray
    sd_bw: np.ndarray
    sd_is_floor: np.ndarray
    ap_mean_bw: np.ndarray
    source: str


@dataclass(frozen=True, eq=False)
class Emg:
    """EMG envelopes of the reference (right) leg over one gait cycle, mapped to model muscles.

    A muscle built from two source channels (HAM, VAS, and GAS for running) is their mean,
    so its peak can be below 1. One subject, one stride: use for timing and shape only.

    Attributes:
      gait_cycle_pct: (N,) percent of the gait cycle.
      muscles: model muscle names, the columns of ``envelope`` (see :data:`EMG_MUSCLES`).
      envelope: (N, M) envelope normalised to the trial maximum [unitless, <= 1]; copied
        as given, so filter undershoot can leave values slightly below 0 (walking TA
        reaches -0.026).
      source_columns: for each muscle, the source columns that were averaged.
      source: data file name.
    """

    gait_cycle_pct: np.ndarray
    muscles: tuple[str, ...]
    envelope: np.ndarray
    source_columns: tuple[tuple[str, ...], ...]
    source: str

    def curve(self, muscle: str) -> np.ndarray:
        """(N,) envelope of model muscle ``muscle`` (e.g. ``"SOL"``)."""
        if muscle not in self.muscles:
            raise KeyError(f"no EMG reference for muscle {muscle!r}; available: {self.muscles}")
        return self.envelope[:, self.muscles.index(muscle)]


# ----------------------------------------------------------------------------- CSV reading


@dataclass(frozen=True)
class _Table:
    path: Path
    columns: dict[str, list[str]]

    def raw(self, name: str) -> list[str]:
        if name not in self.columns:
            raise RefDataError(
                f"{self.path.name}: missing column {name!r}; columns are {list(self.columns)}"
            )
        return self.columns[name]

    def floats(self, name: str, allow_empty_last: bool = False) -> np.ndarray:
        """Column as float64; an empty cell is an error except, if allowed, in the last row."""
        cells = self.raw(name)
        out = np.empty(len(cells))
        for i, cell in enumerate(cells):
            s = cell.strip()
            if s == "" and allow_empty_last and i == len(cells) - 1:
                out[i] = np.nan
                continue
            try:
                out[i] = float(s)
            except ValueError:
                raise RefDataError(
                    f"{self.path.name}: column {name!r}, data row {i + 1}: {cell!r} is not a number"
                ) from None
            if not np.isfinite(out[i]):
                raise RefDataError(
                    f"{self.path.name}: column {name!r}, data row {i + 1}: non-finite {cell!r}"
                )
        return out


def _read_table(data_dir: Path, fname: str) -> _Table:
    path = Path(data_dir) / fname
    if not path.is_file():
        raise FileNotFoundError(f"human reference data file {fname!r} not found in {data_dir}")
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if len(rows) < 3:
        raise RefDataError(f"{fname}: needs a header and at least 2 data rows")
    header = [h.strip() for h in rows[0]]
    for i, r in enumerate(rows[1:], start=1):
        if len(r) != len(header):
            raise RefDataError(
                f"{fname}: data row {i} has {len(r)} cells, header has {len(header)}"
            )
    cols = {h: [r[j] for r in rows[1:]] for j, h in enumerate(header)}
    return _Table(path, cols)


def _cycle_axis(table: _Table) -> np.ndarray:
    pct = table.floats("gait_cycle_pct")
    if np.any(np.diff(pct) <= 0) or pct[0] < 0 or pct[-1] > 100:
        raise RefDataError(
            f"{table.path.name}: column 'gait_cycle_pct' must increase strictly within [0, 100]"
        )
    return pct


def _wrap_last(x: np.ndarray, pct: np.ndarray) -> np.ndarray:
    """Fill a missing value at 100 % with the 0 % value (the cycle is periodic)."""
    if np.isnan(x[-1]) and pct[-1] == 100 and pct[0] == 0:
        x = x.copy()
        x[-1] = x[0]
    return x


def _frozen(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    for a in arrays:
        a.setflags(write=False)
    return arrays


def _resolve(data_dir: str | Path | None) -> Path:
    return _default_data_dir() if data_dir is None else Path(data_dir)


# ----------------------------------------------------------------------------- loaders


def winter_walking_kinematics(data_dir: str | Path | None = None) -> Kinematics:
    """Winter (1991) normal-cadence adult walking angles, 51 samples at 0, 2, ..., 100 %.

    The file has no SD at 100 %; it is taken from 0 % (same instant of a periodic cycle).
    Walking speed 1.325 m/s.
    """
    return _winter_kinematics(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _winter_kinematics(data_dir: Path) -> Kinematics:
    t = _read_table(data_dir, WINTER_KINEMATICS_FILE)
    pct = _cycle_axis(t)
    vals, floors = {}, []
    for j, col in (
        ("hip", "hip_flexion"),
        ("knee", "knee_flexion"),
        ("ankle", "ankle_dorsiflexion"),
    ):
        vals[j + "_mean"] = t.floats(f"{col}_mean_deg")
        sd = _wrap_last(t.floats(f"{col}_sd_deg", allow_empty_last=True), pct)
        fl = _wrap_last(t.floats(f"{col}_sd_is_floor", allow_empty_last=True), pct)
        if np.isnan(sd).any() or np.isnan(fl).any():
            raise RefDataError(f"{t.path.name}: column '{col}_sd_deg' has an empty cell")
        vals[j + "_sd"] = sd
        floors.append(fl > 0.5)
    arrays = _frozen(
        pct,
        vals["hip_mean"],
        vals["hip_sd"],
        vals["knee_mean"],
        vals["knee_sd"],
        vals["ankle_mean"],
        vals["ankle_sd"],
        np.stack(floors, axis=1),
    )
    return Kinematics(*arrays, speed_mps=1.325, source=WINTER_KINEMATICS_FILE)


def winter_walking_grf(data_dir: str | Path | None = None) -> VerticalGRF:
    """Winter (1991) normal-cadence walking GRF [BW], 51 samples; SD at 100 % from 0 %."""
    return _winter_grf(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _winter_grf(data_dir: Path) -> VerticalGRF:
    t = _read_table(data_dir, WINTER_GRF_FILE)
    pct = _cycle_axis(t)
    sd = _wrap_last(t.floats("vertical_grf_sd_BW", allow_empty_last=True), pct)
    fl = _wrap_last(t.floats("vertical_grf_sd_is_floor", allow_empty_last=True), pct)
    if np.isnan(sd).any() or np.isnan(fl).any():
        raise RefDataError(f"{t.path.name}: column 'vertical_grf_sd_BW' has an empty cell")
    arrays = _frozen(
        pct, t.floats("vertical_grf_mean_BW"), sd, fl > 0.5, t.floats("ap_grf_mean_BW")
    )
    return VerticalGRF(*arrays, source=WINTER_GRF_FILE)


def running_kinematics(data_dir: str | Path | None = None) -> Kinematics:
    """Fukuchi et al. (2017) running at 3.5 m/s, mean and SD of 3 subjects, 0..99 %.

    The 50..99 % half comes from the left leg (assumed symmetric, see SOURCES.md).
    """
    return _running_kinematics(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _running_kinematics(data_dir: Path) -> Kinematics:
    t = _read_table(data_dir, RUN_KINEMATICS_FILE)
    pct = _cycle_axis(t)
    cols = []
    for col in ("hip_flexion", "knee_flexion", "ankle_dorsiflexion"):
        cols += [t.floats(f"mean3_{col}_deg"), t.floats(f"sd3_{col}_deg")]
    arrays = _frozen(pct, *cols, np.zeros((pct.shape[0], 3), bool))
    return Kinematics(*arrays, speed_mps=3.5, source=RUN_KINEMATICS_FILE)


def running_grf(data_dir: str | Path | None = None) -> VerticalGRF:
    """Fukuchi et al. (2017) running GRF at 3.5 m/s [BW], mean and SD of 3 subjects."""
    return _running_grf(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _running_grf(data_dir: Path) -> VerticalGRF:
    t = _read_table(data_dir, RUN_GRF_FILE)
    pct = _cycle_axis(t)
    arrays = _frozen(
        pct,
        t.floats("mean3_vertical_grf_BW"),
        t.floats("sd3_vertical_grf_BW"),
        np.zeros(pct.shape[0], bool),
        t.floats("mean3_ap_grf_BW"),
    )
    return VerticalGRF(*arrays, source=RUN_GRF_FILE)


#: Names of the human gait references (joint angles and vertical GRF together).
GAIT_REFERENCES = ("walking", "running")


def gait_reference(name: str) -> tuple[Kinematics, VerticalGRF]:
    """The joint angles and vertical GRF of the human gait ``name``: ``"walking"`` (Winter
    1991, 1.33 m/s) or ``"running"`` (Fukuchi et al. 2017, 3.5 m/s)."""
    if name == "walking":
        return winter_walking_kinematics(), winter_walking_grf()
    if name == "running":
        return running_kinematics(), running_grf()
    raise ValueError(f"unknown gait reference {name!r}; valid: {', '.join(GAIT_REFERENCES)}")


def _emg(data_dir: Path, fname: str, mapping: dict, suffix: str) -> Emg:
    t = _read_table(data_dir, fname)
    pct = _cycle_axis(t)
    env, used = [], []
    for m in EMG_MUSCLES:
        srcs = tuple(c + suffix for c in mapping[m])
        env.append(np.mean([t.floats(c) for c in srcs], axis=0))
        used.append(srcs)
    pct, envelope = _frozen(pct, np.stack(env, axis=1))
    return Emg(pct, EMG_MUSCLES, envelope, tuple(used), fname)


def walking_emg(data_dir: str | Path | None = None) -> Emg:
    """Rajagopal et al. (2016) walking EMG (1 subject, 1 stride, 1.24 m/s), 0..100 %.

    GLU = gluteus maximus, HAM = mean(medial hamstrings, biceps femoris),
    VAS = mean(vastus lateralis, vastus medius), GAS, SOL, TA, RF as named.
    """
    return _walking_emg(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _walking_emg(data_dir: Path) -> Emg:
    return _emg(data_dir, WALK_EMG_FILE, _WALK_EMG_COLUMNS, "")


def running_emg(data_dir: str | Path | None = None) -> Emg:
    """Rajagopal et al. (2016) running EMG (1 subject, 1 stride), 0..100 %.

    GLU = GMAX, HAM = mean(SM, BFLH), VAS = mean(VL, VM), GAS = mean(GASLAT, GASMED),
    SOL, TA, RF as named.
    """
    return _running_emg(_resolve(data_dir))


@functools.lru_cache(maxsize=8)
def _running_emg(data_dir: Path) -> Emg:
    return _emg(data_dir, RUN_EMG_FILE, _RUN_EMG_COLUMNS, _RUN_EMG_SUFFIX)
