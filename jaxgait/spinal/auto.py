"""Automatic control presets and the speed-tracking experiment (thesis 7.3, 8.2).

* :func:`auto_preset`: the preset document of a network model with the closed-loop speed
  law of :mod:`jaxgait.control.autopilot` (``"table": "auto_speed"``, the law's gains as its
  parameters, the network and its FBL parameters as fixed data);
* :func:`anchored_preset`: one speed-controlled model from several network-in-table presets,
  each trained to hold its own constant target (speed anchors: the network's parameters
  interpolated by the target, :func:`jaxgait.control.autopilot.anchored_params`);
* :func:`track`: a target-speed profile (segments of constant v*), one rollout; the speed
  over time and the RMS error of each segment after ``settle_s``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.control.autopilot import AUTO_SPEED, AUTO_SPEED_NET, NET_PREFIX
from jaxgait.control.commands import schedule
from jaxgait.presets import load_preset, preset_from_dict
from jaxgait.spinal.record import SpinalError


def auto_preset(
    network_preset,
    name: str,
    gains: dict | None = None,
    network_in_table: bool = False,
    target_rate: float | None = None,
) -> dict:
    """A speed-controlled version of a network preset (name, path or dict document); with
    ``network_in_table`` the network's FBL parameters are entries of its table as well
    (``net_`` + name, table ``auto_speed_net``), to be trained with the law; ``target_rate``
    [m/s^2] limits how fast the law's target follows the command (``autopilot.target_rate``)."""
    doc = _auto_preset(network_preset, name, gains, network_in_table)
    if target_rate is not None:
        if not target_rate > 0:
            raise SpinalError(f"the target rate limit must be > 0 m/s^2, got {target_rate}")
        doc["autopilot"] = dict(doc["autopilot"], target_rate=float(target_rate))
    return doc


def _auto_preset(network_preset, name, gains, network_in_table) -> dict:
    if isinstance(network_preset, dict):
        model, vec, doc = preset_from_dict(network_preset, where=str(network_preset.get("model")))
    else:
        model, vec, doc = load_preset(network_preset)
    if "network" not in doc:
        raise SpinalError(f"{network_preset}: not a network preset (no 'network' entry)")
    if "autopilot" in doc:
        if network_in_table and not doc["autopilot"].get("network_in_table", False):
            return _network_into_table(doc, name, gains)
        raise SpinalError(f"{network_preset}: already has an automatic controller")
    g = _with_gains(dict(zip(AUTO_SPEED.names, map(float, AUTO_SPEED.init), strict=True)), gains)
    base = dict(zip(models.get_model(model).table.names, map(float, vec), strict=True))
    auto = {"law": "speed", "base_params": base, "source": str(network_preset)}
    table = AUTO_SPEED.name
    if network_in_table:
        g.update({NET_PREFIX + k: v for k, v in base.items()})
        auto["network_in_table"] = True
        table = AUTO_SPEED_NET
    return {
        "model": name,
        "table": table,
        "description": f"{model} with automatic speed control (target v_target [m/s])",
        "params": g,
        "network": doc["network"],
        "autopilot": auto,
    }


def _with_gains(g: dict, gains: dict | None) -> dict:
    """The law's gains ``g`` with the requested ``gains`` replacing theirs (names checked)."""
    unknown = sorted(set(gains or {}) - set(g))
    if unknown:
        raise SpinalError(f"unknown speed-law gains {unknown}; known: {list(g)}")
    return {**g, **{k: float(v) for k, v in (gains or {}).items()}}


def _network_into_table(doc: dict, name: str, gains: dict | None) -> dict:
    """An automatic-control preset with its network's parameters moved into its table."""
    g = _with_gains(dict(doc["params"]), gains)
    auto = dict(doc["autopilot"], network_in_table=True)
    g.update({NET_PREFIX + k: float(v) for k, v in auto["base_params"].items()})
    return {
        **doc,
        "model": name,
        "table": AUTO_SPEED_NET,
        "params": g,
        "autopilot": auto,
    }


def anchored_preset(
    anchor_presets, name: str, speeds=None, grade_presets=(), grades=None, gains=None
) -> dict:
    """One speed-controlled preset whose network parameters are interpolated by the target
    speed between ``anchor_presets`` (names, paths or documents of network-in-table law
    presets, e.g. ``spinal tune --gains 'net_*'`` at a constant target each) and, with
    ``grade_presets`` (one of them trained on level ground), moved with the grade estimate
    by theirs (:mod:`jaxgait.control.autopilot`, speed and grade anchors).  The anchor
    speeds are ``speeds`` [m/s] or each preset's constant tuning target (``tuning.v_range``
    with lo = hi), the grades ``grades`` or each one's ``tuning.grade``; every anchor must
    share the network and the law's gains, of which ``gains`` (name -> value) replace some."""
    docs, vecs = _anchor_docs(anchor_presets)
    gdocs, gvecs = _anchor_docs(grade_presets) if grade_presets else ([], [])
    if not docs:
        raise SpinalError("give at least one anchor preset")
    if speeds is None:
        speeds = [_constant_target(where, doc) for where, doc in docs]
    if grades is None:
        grades = [float((doc.get("tuning") or {}).get("grade", 0.0)) for _, doc in gdocs]
    if len(speeds) != len(docs) or len(grades) != len(gdocs):
        raise SpinalError(
            f"{len(docs)} speed and {len(gdocs)} grade anchor presets but {len(speeds)} "
            f"speeds and {len(grades)} grades"
        )
    law = {k: v for k, v in vecs[0].items() if not k.startswith(NET_PREFIX)}
    for (where, doc), g in zip(docs + gdocs, vecs + gvecs, strict=True):
        if doc["network"] != docs[0][1]["network"]:
            raise SpinalError(f"{where}: its network differs from {docs[0][0]}'s")
        diff = sorted(k for k in law if g[k] != law[k])
        if diff:
            raise SpinalError(f"{where}: its law gains {diff} differ from {docs[0][0]}'s")
    anchors = _anchor_list(speeds, vecs, "v", "anchor speeds")
    first = docs[0][1]
    auto = {
        "law": "speed",
        "base_params": anchors[0]["params"],
        "anchors": anchors,
        "source": [where for where, _ in docs + gdocs],
    }
    text = ", ".join(f"{a['v']:.2f}" for a in anchors) + " m/s"
    if gdocs:
        if 0.0 not in [float(g) for g in grades]:
            raise SpinalError(f"the grade anchors need one at grade 0, got {list(grades)}")
        auto["grade_anchors"] = _anchor_list(grades, gvecs, "grade", "anchor grades")
        text += " and grades " + ", ".join(f"{g:.2f}" for g in sorted(grades))
    if first["autopilot"].get("target_rate") is not None:
        auto["target_rate"] = first["autopilot"]["target_rate"]
    return {
        "model": name,
        "table": AUTO_SPEED.name,
        "description": f"speed-controlled network, its FBL parameters interpolated between "
        f"anchors at {text}",
        "params": _with_gains(law, gains),
        "network": first["network"],
        "autopilot": auto,
        **{k: first[k] for k in ("v0", "pose") if k in first},
    }


def _anchor_docs(presets) -> tuple[list, list]:
    """(where, document) and table-value dicts of network-in-table law presets."""
    docs, vecs = [], []
    for a in presets:
        where = str(a.get("model")) if isinstance(a, dict) else str(a)
        model, vec, doc = (
            preset_from_dict(a, where=where) if isinstance(a, dict) else load_preset(a)
        )
        auto = doc.get("autopilot") or {}
        if not auto.get("network_in_table", False):
            raise SpinalError(f"{where}: an anchor must have its network in its table")
        docs.append((where, doc))
        vecs.append(dict(zip(models.get_model(model).table.names, map(float, vec), strict=True)))
    return docs, vecs


def _anchor_list(points, vecs, key: str, what: str) -> list[dict]:
    """[{key: point, "params": network parameters}, ...] in increasing order of the points."""
    order = np.argsort(points)
    if np.any(np.diff(np.asarray(points, float)[order]) <= 0):
        raise SpinalError(f"{what} must differ, got {list(points)}")
    return [
        {
            key: float(points[k]),
            "params": {
                n[len(NET_PREFIX) :]: v for n, v in vecs[k].items() if n.startswith(NET_PREFIX)
            },
        }
        for k in order
    ]


def _constant_target(where: str, doc: dict) -> float:
    """The constant target an anchor preset was trained on (``tuning.v_range`` lo = hi)."""
    lo, hi = (doc.get("tuning") or {}).get("v_range", (None, None))
    if lo is None or lo != hi:
        raise SpinalError(
            f"{where}: not trained at one constant target (tuning.v_range {lo}, {hi}); "
            "give --speeds"
        )
    return float(lo)


def profile_schedules(commands, profiles, segment_s: float):
    """Batch of hold schedules of v_target, one per row of ``profiles`` (n, segments) [m/s],
    each target held ``segment_s`` seconds."""
    rows = [
        schedule(commands, [(k * segment_s, {"v_target": float(v)}) for k, v in enumerate(p)])
        for p in np.asarray(profiles)
    ]
    return jax.tree.map(lambda *a: jnp.stack(a), *rows)


def moving_speed(t, x, log_dt: float, window_s: float = 1.0) -> np.ndarray:
    """(..., T) backward moving-average speed over ``window_s`` [m/s] of a path x(t) logged
    every ``log_dt`` seconds (NaN for the first window)."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    n = max(1, int(round(window_s / log_dt)))
    v = np.full(x.shape, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):  # rows after a fall repeat t
        v[..., n:] = (x[..., n:] - x[..., :-n]) / (t[..., n:] - t[..., :-n])
    return v


def track(preset, profile, segment_s: float = 20.0, settle_s: float = 5.0, env=None) -> dict:
    """Run ``preset`` (a model with a ``v_target`` command) through the target ``profile``
    [m/s], ``segment_s`` seconds each; returns time, speed (1 s moving average), target and
    the per-segment RMS error after ``settle_s`` (NaN after a fall)."""
    from jaxgait.world import envs

    name, vec, doc = load_preset(preset)
    model = models.get_model(name)
    if "v_target" not in model.controller.command_names:
        raise SpinalError(f"{preset}: model {name!r} has no v_target command")
    knots = [(k * segment_s, {"v_target": float(v)}) for k, v in enumerate(profile)]
    sched = schedule(model.controller.commands, knots)
    cfg = sim.SimConfig(duration=segment_s * len(profile), max_events=2048)
    e = env if env is not None else envs.make_env("flat", jax.random.PRNGKey(0))
    f = sim.make_rollout(model, cfg, batched=False)
    tr, _, sm, _ = f(model.table.as_jnp(vec), e, sched)
    t = np.asarray(tr.t, float)
    alive = np.asarray(tr.alive, bool)
    x = np.asarray(tr.com, float)[:, 0]
    v = moving_speed(t, x, cfg.log_dt)
    v[~alive] = np.nan
    target = np.asarray([profile[min(int(ti // segment_s), len(profile) - 1)] for ti in t])
    target[~alive] = np.nan  # the log's rows after a fall are not times of the walk
    rms = []
    for k in range(len(profile)):
        w = (t >= k * segment_s + settle_s) & (t < (k + 1) * segment_s)
        ok = w & alive
        rms.append(
            float(np.sqrt(np.mean((v[ok] - target[ok]) ** 2)))
            if 0 < ok.sum() == w.sum()
            else np.nan
        )
    return {
        "model": name,
        "profile": list(map(float, profile)),
        "segment_s": segment_s,
        "settle_s": settle_s,
        "t": t,
        "speed": v,
        "target": target,
        "rms": rms,
        "fell": bool(np.asarray(sm.fell)),
        "duration_s": float(np.asarray(sm.duration)),
    }


def speed_range(
    preset, targets, duration_s: float = 30.0, measure_s: float = 10.0, tol: float = 0.1
) -> dict:
    """Constant targets held for ``duration_s`` each (one batched rollout per target, flat
    ground): a target is *held* when the walker does not fall and its mean speed over the
    last ``measure_s`` seconds is within ``tol`` [m/s] of it.  Returns per target the mean
    speed and the flags, and the slowest and fastest held targets (and whether every
    target between them is held)."""
    from jaxgait.world import envs

    name, vec, doc = load_preset(preset)
    model = models.get_model(name)
    if "v_target" not in model.controller.command_names:
        raise SpinalError(f"{preset}: model {name!r} has no v_target command")
    if not 0 < measure_s <= duration_s:
        raise SpinalError(f"need 0 < measure_s <= duration_s, got {measure_s}, {duration_s}")
    targets = np.asarray(targets, float)
    sched = profile_schedules(model.controller.commands, targets[:, None], duration_s)
    cfg = sim.SimConfig(duration=duration_s, log_dt=0.1, v0=float(doc.get("v0", sim.SimConfig.v0)))
    n = targets.size
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), n))
    f = sim.make_rollout(model, cfg, batched=True)
    params = jnp.broadcast_to(model.table.as_jnp(vec), (n, model.table.size))
    tr, _, sm, _ = f(params, env, sched)
    t = np.asarray(tr.t, float)
    x = np.asarray(tr.com, float)[..., 0]
    fell = np.asarray(sm.fell, bool)
    speed = np.full(n, np.nan)
    for k in range(n):
        w = t[k] >= duration_s - measure_s - 1e-9
        if not fell[k] and w.sum() >= 2:
            i0, i1 = np.flatnonzero(w)[[0, -1]]
            speed[k] = (x[k, i1] - x[k, i0]) / (t[k, i1] - t[k, i0])
    held = (~fell) & (np.abs(speed - targets) <= tol)
    idx = np.flatnonzero(held)
    slowest = float(targets[idx].min()) if idx.size else None
    fastest = float(targets[idx].max()) if idx.size else None
    contiguous = bool(idx.size and held[idx.min() : idx.max() + 1].all())
    return {
        "model": name,
        "targets": targets.tolist(),
        "speed_mps": speed.tolist(),
        "fell": fell.tolist(),
        "held": held.tolist(),
        "tol_mps": tol,
        "duration_s": duration_s,
        "measure_s": measure_s,
        "slowest_held_mps": slowest,
        "fastest_held_mps": fastest,
        "all_between_held": contiguous,
    }
