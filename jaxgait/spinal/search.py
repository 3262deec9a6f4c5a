"""Systematic searches of the control vector during walking (thesis 7.3.2-7.3.3, Fig. 7.6-7.10).

A search varies two commands of a network model over a grid (``x`` values by ``y`` values),
the other commands held at their defaults or at ``fixed`` values.  Each column of the grid
(one y value) is one continuous rollout: C is changed every ``hold_s`` seconds (10 s in the
thesis) through the x values in increasing order and the gait is measured over the last
``measure_s`` seconds of each setting (4 s; the first 6 s let it settle).  Each column first
walks ``warmup_s`` seconds at the default control vector (the feedforward interneurons switch
on and the start transient dies out before the first setting).  A fall ends its
column: that setting and the later ones are blank (NaN), as the white cells of the thesis's
maps.  The columns run as one batch (``vmap`` over their schedules).  An optional third
command ``z`` (omega in thesis Fig. 7.9-7.10) repeats the grid for each of its values in the
same batch: the measures then have the shape (len(z), len(y), len(x)).

Per setting (:func:`window_measures`): mean speed [m/s], energy per metre [J/m], fraction of
time in double stance [-] and its duration per cycle [s], cycle frequency and length [Hz, s]
(right-leg touchdowns), step-length variance [m^2].  :func:`fit_speed_law` fits thesis
eq. 7.1, S = a1 x + a2 y + a3, by least squares over the settings that walked.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.control.commands import schedule
from jaxgait.presets import load_preset
from jaxgait.spinal.record import SpinalError
from jaxgait.world import envs

MEASURES = (
    "speed_mps",
    "energy_J_per_m",
    "double_stance_fraction",
    "double_stance_s",
    "cycle_frequency_hz",
    "cycle_length_s",
    "step_length_var_m2",
)


@dataclass(frozen=True)
class Search:
    """A grid of two commands (names and values) and the held settings."""

    x: str
    x_values: tuple[float, ...]
    y: str
    y_values: tuple[float, ...]
    fixed: dict = field(default_factory=dict)
    hold_s: float = 10.0
    measure_s: float = 4.0
    warmup_s: float = 10.0
    z: str | None = None
    z_values: tuple[float, ...] = ()

    def __post_init__(self):
        if self.x == self.y:
            raise SpinalError(f"the two searched commands must differ, got {self.x!r} twice")
        if self.z is not None and (self.z in (self.x, self.y) or not self.z_values):
            raise SpinalError(f"the third command {self.z!r} must differ and have values")
        if not (0 < self.measure_s <= self.hold_s):
            raise SpinalError(f"need 0 < measure_s <= hold_s, got {self.measure_s}, {self.hold_s}")
        if self.warmup_s < 0:
            raise SpinalError(f"warmup_s must be >= 0, got {self.warmup_s}")
        if not self.x_values or not self.y_values:
            raise SpinalError("a search needs at least one value of each command")


def windows(search: Search) -> list[tuple[float, float]]:
    """(start, end) [s] of the measuring window of each x setting in a column."""
    h, m, w = search.hold_s, search.measure_s, search.warmup_s
    return [(w + (j + 1) * h - m, w + (j + 1) * h) for j in range(len(search.x_values))]


def columns(search: Search) -> list[dict]:
    """The held commands of each column: z values (outer) by y values (inner)."""
    zs = [{search.z: float(v)} for v in search.z_values] if search.z is not None else [{}]
    return [{**search.fixed, **z, search.y: float(yv)} for z in zs for yv in search.y_values]


def column_schedules(commands, search: Search):
    """The batch (one per column, :func:`columns`) of hold schedules stepping through x."""
    names = {c.name for c in commands}
    for n in (search.x, search.y, *([search.z] if search.z else []), *search.fixed):
        if n not in names:
            raise SpinalError(f"command {n!r} is not one of this model's: {sorted(names)}")
    cols = []
    for held in columns(search):
        knots = [(0.0, {})] if search.warmup_s > 0 else []
        knots += [
            (search.warmup_s + j * search.hold_s, {**held, search.x: float(xv)})
            for j, xv in enumerate(search.x_values)
        ]
        cols.append(schedule(commands, knots))
    return jax.tree.map(lambda *a: jnp.stack(a), *cols)


def window_measures(trace, events, windows_s, fell_at: float = np.inf) -> dict[str, np.ndarray]:
    """Gait measures of one rollout in each window (host arrays; NaN for the windows that end
    after ``fell_at``, the time of the fall [s]).  trace/events: one rollout (no batch axis).
    (The trace's ``alive`` flag is not used: the row at the time limit is already "done".)"""
    t = np.asarray(trace.t, float)
    com_x = np.asarray(trace.com, float)[:, 0]
    energy = np.asarray(trace.energy, float)
    stance = np.asarray(trace.stance, bool)
    n_ev = min(int(np.asarray(events.n)), np.asarray(events.t).shape[0])
    ev_t = np.asarray(events.t, float)[:n_ev]
    ev_leg = np.asarray(events.leg)[:n_ev]
    step = (np.asarray(events.x_td, float) - np.asarray(events.x_other, float))[:n_ev]
    out = {k: np.full(len(windows_s), np.nan) for k in MEASURES}
    for j, (a, b) in enumerate(windows_s):
        rows = (t > a + 1e-6) & (t <= b + 1e-6)
        if rows.sum() < 2 or fell_at <= b + 1e-6:
            continue
        i0, i1 = np.flatnonzero(rows)[[0, -1]]
        dx = com_x[i1] - com_x[i0]
        dt = t[i1] - t[i0]
        out["speed_mps"][j] = dx / dt
        out["energy_J_per_m"][j] = (energy[i1] - energy[i0]) / dx if dx > 1e-6 else np.nan
        ds = float(np.mean(stance[rows, 0] & stance[rows, 1]))
        out["double_stance_fraction"][j] = ds
        td = ev_t[(ev_t > a) & (ev_t <= b) & (ev_leg == 0)]
        if td.size >= 2:
            cyc = float(np.mean(np.diff(td)))
            out["cycle_length_s"][j] = cyc
            out["cycle_frequency_hz"][j] = 1.0 / cyc
            out["double_stance_s"][j] = ds * cyc
        st = step[(ev_t > a) & (ev_t <= b)]
        if st.size >= 2:
            out["step_length_var_m2"][j] = float(np.var(st))
    return out


@functools.lru_cache(maxsize=4)
def _rollout(model, cfg: sim.SimConfig):
    """The batched rollout of one model object (a re-registered name is a new object)."""
    return sim.make_rollout(model, cfg, batched=True)


def run_search(preset, search: Search, env: str = "flat", seed: int = 0) -> dict:
    """Run a search on a network preset: ``{measure: (len(y), len(x)) array}`` (with ``z``:
    (len(z), len(y), len(x))) plus the grid, the model name and the falls per column."""
    name, vec, doc = load_preset(preset)
    model = models.get_model(name)
    sched = column_schedules(model.controller.commands, search)
    ny, nx = len(columns(search)), len(search.x_values)
    duration = search.warmup_s + nx * search.hold_s
    cfg = sim.SimConfig(
        duration=duration,
        v0=float(doc.get("v0", sim.SimConfig.v0)),
        max_events=max(512, int(4 * duration)),
    )
    keys = jax.random.split(jax.random.PRNGKey(int(seed)), ny)
    env_b = envs.make_env_batch(env, keys)
    params = jnp.broadcast_to(model.table.as_jnp(vec), (ny, model.table.size))
    trace, events, summary, _ = _rollout(model, cfg)(params, env_b, sched)
    trace, events = jax.tree.map(np.asarray, trace), jax.tree.map(np.asarray, events)
    fell = np.asarray(summary.fell, bool)
    fell_at = np.where(fell, np.asarray(summary.duration, float), np.inf)
    wins = windows(search)
    grid = {k: np.full((ny, nx), np.nan) for k in MEASURES}
    for i in range(ny):
        one_t = jax.tree.map(lambda x, i=i: x[i], trace)
        one_e = jax.tree.map(lambda x, i=i: x[i], events)
        for k, v in window_measures(one_t, one_e, wins, float(fell_at[i])).items():
            grid[k][i] = v
    if search.z is not None:
        grid = {
            k: v.reshape(len(search.z_values), len(search.y_values), nx) for k, v in grid.items()
        }
    return {
        "model": name,
        "x": search.x,
        "x_values": list(search.x_values),
        "y": search.y,
        "y_values": list(search.y_values),
        "fixed": dict(search.fixed),
        **({"z": search.z, "z_values": list(search.z_values)} if search.z else {}),
        "hold_s": search.hold_s,
        "measure_s": search.measure_s,
        "warmup_s": search.warmup_s,
        "fell": fell.tolist(),
        "fell_at_s": [float(v) if np.isfinite(v) else None for v in fell_at],
        "grid": grid,
    }


def fit_speed_law(x_values, y_values, speed) -> dict:
    """Least-squares fit of thesis eq. 7.1, S = a1 x + a2 y + a3, over the finite cells of
    ``speed`` (len(y), len(x)); returns a1, a2, a3, the RMS residual and the cell count."""
    X, Y = np.meshgrid(np.asarray(x_values, float), np.asarray(y_values, float))
    S = np.asarray(speed, float)
    ok = np.isfinite(S)
    if ok.sum() < 3:
        raise SpinalError(f"the speed law needs at least 3 settings that walked, got {ok.sum()}")
    A = np.stack([X[ok], Y[ok], np.ones(ok.sum())], 1)
    coef, *_ = np.linalg.lstsq(A, S[ok], rcond=None)
    rms = float(np.sqrt(np.mean((A @ coef - S[ok]) ** 2)))
    return {
        "a1": float(coef[0]),
        "a2": float(coef[1]),
        "a3": float(coef[2]),
        "rms": rms,
        "n": int(ok.sum()),
    }
