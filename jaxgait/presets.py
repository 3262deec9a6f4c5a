"""Parameter presets: named JSON files of controller parameters, loaded and validated.

A preset is a JSON object (written by :func:`jaxgait.core.params.save_preset`)::

    {"model": "fbl", "table": "fbl", "description": "...", "params": {"k_bw": 1.2, ...}}

* ``model``: the model family the parameters belong to (default ``"fbl"``);
* ``table``: the :class:`~jaxgait.core.params.ParamTable` the names refer to (default: the model
  name);
* ``params``: name -> value, in the units of the table (see ``ParamTable.to_table``);
* ``partial`` (optional, default false): names missing from ``params`` take the table's
  initial values instead of being an error;
* any other key is free metadata (description, score, provenance...).

Shipped presets live in :func:`jaxgait.core.resources.presets_dir` (``experiments/presets`` in a
source checkout) and are referred to by file stem: ``load_preset("geyer_walk")``. Anything
else is a path to a JSON file, or to a results folder holding ``best.json`` (as written by
the search scripts).

The models and their tables are those of the registry (:mod:`jaxgait.models`).  Presets of
a model without a parameter table (the ``taga`` family) are passed through unvalidated (the
raw dict is in the returned document) for :mod:`jaxgait.taga` to check.

Every problem raises :class:`PresetError` (a ``ValueError``) whose message starts with the
file (or ``where``) and says what is wrong: missing file (with the available preset names),
invalid JSON (with line and column), no ``params``, unknown or missing parameter names,
non-numeric values and values outside their range.
"""

from __future__ import annotations

import difflib
import json
from pathlib import Path

import numpy as np

from jaxgait import models
from jaxgait.control.fblankle import FBL_ANKLE, lift_fbl_ankle
from jaxgait.control.fblplus import FBLPLUS, lift_fbl
from jaxgait.control.fblplus_bal import FBLPLUS_BAL, lift_fblplus
from jaxgait.control.network_json import network_from_dict
from jaxgait.control.spinal import NetworkError, spinal_controller
from jaxgait.core.params import ParamTable, save_preset
from jaxgait.core.resources import presets_dir

#: File looked for inside a results folder.
RESULTS_FILE = "best.json"


class PresetError(ValueError):
    """A preset cannot be found, parsed or validated; the message names the file."""


# --------------------------------------------------------------------------- registry


def param_tables() -> dict[str, ParamTable]:
    """Every parameter table of the registered models (:func:`jaxgait.models.param_tables`)."""
    return models.param_tables()


def available_models() -> tuple[str, ...]:
    """Model names a preset may declare: the registered models."""
    return models.model_names()


def _pass_through(model: str) -> bool:
    """A registered model whose presets are not a parameter table (Taga)."""
    return model in models.model_names() and models.get_spec(model).table is None


def _presets_dir() -> Path | None:
    try:
        return presets_dir()
    except FileNotFoundError:
        return None


def list_presets() -> list[str]:
    """Names (file stems) of the shipped presets, sorted; empty if none are shipped."""
    d = _presets_dir()
    if d is None:
        return []
    return sorted(p.stem for p in d.glob("*.json") if p.is_file())


def _available_text() -> str:
    names = list_presets()
    return "available presets: " + (", ".join(names) if names else "(none shipped)")


def _is_bare_name(s: str) -> bool:
    return "/" not in s and "\\" not in s and not s.endswith(".json") and s not in (".", "..")


def resolve_preset(name_or_path: str | Path) -> Path:
    """Path of the JSON file a preset name, file path or results folder refers to.

    A bare name (no directory part, no ``.json``) is looked up as
    ``presets_dir()/NAME.json`` first; otherwise (or if there is no such preset) the
    argument is a path: a JSON file, or a folder holding ``best.json``.

    Raises:
      PresetError: nothing found; the message lists the shipped preset names.
    """
    s = str(name_or_path)
    if not s.strip():
        raise PresetError(f"empty preset name; {_available_text()}")
    d = _presets_dir()
    if isinstance(name_or_path, str) and _is_bare_name(s) and d is not None:
        cand = d / f"{s}.json"
        if cand.is_file():
            return cand
    p = Path(s).expanduser()
    if p.is_dir():
        best = p / RESULTS_FILE
        if best.is_file():
            return best
        raise PresetError(f"{p}: folder has no {RESULTS_FILE} (not a results folder)")
    if p.is_file():
        return p
    if _is_bare_name(s):
        where = f"{d}/{s}.json" if d is not None else "the presets folder (not found)"
        raise PresetError(f"{s}: no preset of that name (looked for {where}); {_available_text()}")
    raise PresetError(f"{p}: file not found; {_available_text()}")


# --------------------------------------------------------------------------- networks

#: model name -> the preset entries that define it (``network`` and, for an automatically
#: controlled model, ``autopilot``), for the models registered by this module
_NETWORKS: dict[str, dict] = {}


def _register_network(doc: dict, model: str, where: str) -> None:
    """Register the spinal-network model a preset defines (``"network"`` entry) under its
    ``model`` name; a name already registered with the same network is kept, one with
    another network is replaced (a rebuilt model), a built-in model name is refused."""
    entries = {k: doc[k] for k in ("network", "autopilot") if k in doc}
    if _NETWORKS.get(model) == entries:
        return
    if model in models.model_names() and model not in _NETWORKS:
        raise PresetError(
            f"{where}: a network preset cannot take the name of the built-in model {model!r}"
        )
    auto = doc.get("autopilot")
    try:
        net = network_from_dict(doc["network"], model, str(doc.get("description", "")), where)
    except NetworkError as e:
        raise PresetError(str(e)) from None
    table = doc.get("table", "fbl")
    if auto is not None and net.base != "fbl":
        raise PresetError(f"{where}: automatic speed control drives FBL networks only")
    from jaxgait.control.autopilot import AUTO_SPEED, AUTO_SPEED_NET

    want = net.base
    if auto is not None:
        want = AUTO_SPEED_NET if _network_in_table(auto, where) else AUTO_SPEED.name
    if table != want:
        raise PresetError(
            f"{where}: a network model on {net.base!r} drives the table {net.base!r} (its "
            f"automatic speed control the {AUTO_SPEED.name!r} table, or {AUTO_SPEED_NET!r} "
            f"with autopilot.network_in_table), not {table!r}"
        )
    ctrl = spinal_controller(net)
    if auto is not None:
        ctrl = _autopilot(auto, ctrl, model, where)
    models.register(models.planar_spec(ctrl), replace=True)
    _NETWORKS[model] = json.loads(json.dumps(entries))  # a copy the caller cannot change


def _network_in_table(auto, where: str) -> bool:
    """The ``autopilot.network_in_table`` flag (false when absent)."""
    flag = auto.get("network_in_table", False) if isinstance(auto, dict) else False
    if not isinstance(flag, bool):
        raise PresetError(f"{where}: autopilot.network_in_table must be true or false")
    return flag


def _autopilot(auto, inner, model: str, where: str):
    """The automatic speed controller of a preset's ``autopilot`` entry around ``inner``."""
    from jaxgait.control.autopilot import speed_controller

    if not isinstance(auto, dict) or auto.get("law") != "speed":
        raise PresetError(f'{where}: \'autopilot\' must be {{"law": "speed", "base_params": ...}}')
    vec = _fbl_vector(
        auto.get("base_params"), where, "autopilot.base_params", f"{where} (autopilot.base_params)"
    )
    rate = auto.get("target_rate")
    if rate is not None and (
        isinstance(rate, bool) or not isinstance(rate, (int, float)) or rate <= 0
    ):
        raise PresetError(
            f"{where}: autopilot.target_rate must be a number > 0 [m/s^2], got {rate!r}"
        )
    try:
        return speed_controller(
            model,
            inner,
            vec,
            network_in_table=_network_in_table(auto, where),
            target_rate=None if rate is None else float(rate),
            anchors=_anchors(auto, where),
            grade_anchors=_anchors(auto, where, "grade_anchors", "grade"),
        )
    except ValueError as e:
        raise PresetError(f"{where}: {e}") from None


def _anchors(auto: dict, where: str, entry: str = "anchors", key: str = "v"):
    """The ``autopilot.anchors`` entry, [{"v": v_k [m/s], "params": {FBL name: value}}, ...]
    (or ``grade_anchors``, [{"grade": g_j, "params": ...}, ...]) as (v_k, FBL vector) pairs,
    each vector checked against FBL's ranges (None when absent)."""
    raw = auto.get(entry)
    if raw is None:
        return None
    if not isinstance(raw, list) or not raw:
        raise PresetError(
            f'{where}: autopilot.{entry} must be a list of {{"{key}": ..., "params": ...}}'
        )
    out = []
    for k, a in enumerate(raw):
        at = f"{where} (autopilot.{entry}[{k}])"
        if not isinstance(a, dict) or set(a) != {key, "params"}:
            raise PresetError(f'{at}: an anchor is {{"{key}": number, "params": {{...}}}}')
        out.append((_number(at, key, a[key]), _fbl_vector(a["params"], at, "params", at)))
    return out


def _fbl_vector(q, where: str, entry: str, check_at: str):
    """The FBL vector of a {name: value} entry that must give every FBL parameter, each a
    number within FBL's range (errors name ``entry`` after ``where``; range errors
    ``check_at``)."""
    from jaxgait.control.fbl import FBL

    if not isinstance(q, dict) or sorted(q) != sorted(FBL.names):
        raise PresetError(f"{where}: {entry} must give all {FBL.size} FBL parameters")
    vec = FBL.pack({n: _number(where, n, x) for n, x in q.items()})
    try:
        FBL.check(vec, where=check_at)
    except ValueError as e:
        raise PresetError(str(e)) from None
    return vec


def defining_entries(name: str) -> dict:
    """The preset entries (``network``, ``autopilot``) that define model ``name``, for a
    preset that re-creates it (e.g. a training run's ``best.json``); {} for a built-in."""
    return json.loads(json.dumps(_NETWORKS.get(name, {})))


def ensure_model(name: str, init=None) -> bool:
    """Whether ``name`` is a registered planar model, registering it first when a preset
    defines it: the ``init`` preset (a name or file that defines ``name``) or a shipped
    preset of that name."""
    if name in models.model_names("planar"):
        return True
    if isinstance(init, (str, Path)) and init != "table":
        try:
            load_preset(init)
        except PresetError:
            pass
    if name not in models.model_names("planar"):
        try:
            models.get_spec(name)
        except KeyError:
            return False
    return name in models.model_names("planar")


def forget_network(name: str) -> None:
    """Unregister a network model this module registered (e.g. a trial model)."""
    if _NETWORKS.pop(name, None) is not None:
        models.unregister(name)


def _resolve_network_model(name: str) -> bool:
    """Model resolver: a shipped preset of that name that defines a network."""
    d = _presets_dir()
    path = d / f"{name}.json" if d is not None and _is_bare_name(name) else None
    if path is None or not path.is_file():
        return False
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return False
    if not isinstance(doc, dict) or "network" not in doc or doc.get("model") != name:
        return False
    _register_network(doc, name, str(path))
    return True


models.add_resolver(_resolve_network_model)


# --------------------------------------------------------------------------- validation


def _number(where: str, name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PresetError(f"{where}: parameter {name!r} has value {v!r}, not a number")
    return float(v)


def preset_from_dict(doc, where: str = "preset") -> tuple[str, np.ndarray, dict]:
    """Validate a parsed preset document; see :func:`load_preset` for the result.

    Args:
      doc: the JSON object (a dict).
      where: label used at the start of error messages (the file name).
    """
    if not isinstance(doc, dict):
        raise PresetError(f"{where}: a preset must be a JSON object, got {type(doc).__name__}")
    model = doc.get("model", "fbl")
    if not isinstance(model, str):
        raise PresetError(f"{where}: 'model' must be a string, got {model!r}")
    if "params" not in doc:
        raise PresetError(f"{where}: no 'params' entry (expected {{name: value, ...}})")
    raw = doc["params"]
    if "network" in doc:
        _register_network(doc, model, where)
    if _pass_through(model):
        return model, np.zeros(0), doc
    if not isinstance(raw, dict):
        raise PresetError(f"{where}: 'params' must be an object {{name: value}}, got {raw!r:.60}")
    tables = param_tables()
    table_name = doc.get("table", model)
    if model not in tables and table_name not in tables:
        raise PresetError(
            f"{where}: model {model!r} is not available in this version of jaxgait "
            f"(available: {', '.join(available_models())})"
        )
    if table_name not in tables:
        raise PresetError(
            f"{where}: unknown parameter table {table_name!r} (available: {', '.join(tables)})"
        )
    table = tables[table_name]

    unknown = [k for k in raw if k not in table.names]
    if unknown:
        hints = []
        for k in unknown:
            close = difflib.get_close_matches(k, table.names, n=1)
            hints.append(f"{k} (did you mean {close[0]}?)" if close else k)
        raise PresetError(
            f"{where}: unknown parameter(s) for table {table.name!r}: {', '.join(hints)}"
        )
    values = {k: _number(where, k, v) for k, v in raw.items()}
    missing = [n for n in table.names if n not in values]
    partial = doc.get("partial", False)
    if missing and partial is not True:
        raise PresetError(
            f"{where}: missing parameter(s) for table {table.name!r}: {', '.join(missing)} "
            '(add them, or set "partial": true to take the table\'s initial values)'
        )
    vec = table.pack(values)
    try:
        table.check(vec, where=where)
    except ValueError as e:
        raise PresetError(str(e)) from None
    return model, vec, doc


def load_preset(name_or_path: str | Path) -> tuple[str, np.ndarray, dict]:
    """Load and validate a preset.

    Args:
      name_or_path: a shipped preset name (``presets_dir()/NAME.json``), a path to a preset
        JSON file, or a results folder containing ``best.json``.

    Returns:
      ``(model_name, vec, doc)``: the model family (e.g. ``"fbl"``), the (D,) float64
      parameter vector in the order of the preset's table (units of the table; an empty
      array for pass-through models such as ``"taga"``, whose parameters stay in
      ``doc["params"]``) and the parsed JSON document.

    Raises:
      PresetError: with the file name and what is wrong.
    """
    path = resolve_preset(name_or_path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise PresetError(f"{path}: cannot read preset file: {e}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise PresetError(
            f"{path}: invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}"
        ) from None
    return preset_from_dict(doc, where=str(path))


def preset_dynamics(doc: dict) -> str:
    """The multibody dynamics a preset (or a results ``config.json``'s experiment) was made
    with: its ``dynamics`` entry, or ``"mjx"`` without one (``train`` writes the entry only
    for the planar tree; everything made before the option ran MJX's passes)."""
    return doc.get("dynamics", "mjx")


#: Models that extend another with neutral extras: model -> (table, source model, lift
#: function, description of the neutral extras).  A neutral preset of one walks like its
#: source (module docstrings: FBL+ bit for bit, fbl_ankle and fblplus_bal to float32
#: rounding).
_NEUTRAL_LIFTS = {
    "fblplus": (
        FBLPLUS,
        "fbl",
        lift_fbl,
        "FBL+ walking on flat ground (thesis 2.1.3): the FBL walking preset {source} with the "
        "10 extra FBL+ parameters neutral: swing-end PD gains kp/kd of HFL, GLU and VAS = 0, "
        "stance-end CoM threshold d_st_end = 3 foot lengths (its upper bound, never reached "
        "in stance, so stance end comes from double support only, as in FBL), hip/knee "
        "targets and d_sw_end at the table's initial values (inactive with zero gains). "
        "It walks exactly like the source preset.",
    ),
    "fbl_ankle": (
        FBL_ANKLE,
        "fbl",
        lift_fbl_ankle,
        "fbl_ankle (jaxgait.control.fblankle): the FBL walking preset {source} with the 3 "
        "ankle extras neutral: swing SOL and GAS drive k_sw = 1 (FBL's S0) and no TA "
        "foot-lowering damping (G_TA_v = 0).  The same law as FBL's: it walks like the source "
        "preset, to float32 rounding.",
    ),
    "fblplus_bal": (
        FBLPLUS_BAL,
        "fblplus",
        lift_fblplus,
        "fblplus_bal (jaxgait.control.fblplus_bal): the FBL+ preset {source} with SIMBICON's "
        "foot-placement gains c_d = c_v = 0, so the swing-end hip target is FBL+'s.  It "
        "moves like the source preset, to float32 rounding.",
    ),
}


def write_neutral_preset(src, dst, model: str = "fblplus") -> np.ndarray:
    """Write the ``model`` preset ``dst`` made of the preset ``src`` and neutral extras.

    ``model`` is ``"fblplus"`` (``src`` an FBL preset; see "Reduction to FBL" in
    :mod:`jaxgait.control.fblplus`), ``"fbl_ankle"`` (FBL source,
    :mod:`jaxgait.control.fblankle`) or ``"fblplus_bal"`` (FBL+ source,
    :mod:`jaxgait.control.fblplus_bal`); the result moves like ``src`` (FBL+: bit for bit;
    the others to float32 rounding), which is anything :func:`load_preset` accepts.
    Returns the vector.
    """
    if model not in _NEUTRAL_LIFTS:
        raise ValueError(f"no neutral lift to model {model!r}; known: {', '.join(_NEUTRAL_LIFTS)}")
    table, needed, lift, text = _NEUTRAL_LIFTS[model]
    path = resolve_preset(src)
    src_model, vec, src_doc = load_preset(path)
    if src_model != needed:
        raise ValueError(
            f"{path}: a {needed!r} preset is needed for {model!r}, this one is for model "
            f"{src_model!r}"
        )
    try:
        source = path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        source = str(path)
    lifted = lift(vec)
    table.check(lifted, where=str(dst))
    # the source's start and dynamics
    start = {k: src_doc[k] for k in ("v0", "pose", "dynamics") if k in src_doc}
    save_preset(
        Path(dst),
        model,
        table,
        lifted,
        description=text.format(source=source),
        source=source,
        extras_neutral=True,
        **start,
    )
    return lifted
