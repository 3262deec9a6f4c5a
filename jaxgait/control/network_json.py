"""The JSON form of a spinal :class:`~jaxgait.control.spinal.Network` (the ``network`` entry
of a network preset): per-IN entries keyed by the IN_SEN names of
:data:`jaxgait.control.interneurons.IN_NAMES`, CPG patterns as lists of knot values."""

from __future__ import annotations

import numpy as np

from jaxgait.control.interneurons import IN_NAMES, N_IN
from jaxgait.control.spinal import TAU_IN, TAU_MN, Network, NetworkError


def network_to_dict(net: Network) -> dict:
    """The JSON form of a network (per-IN entries keyed by IN_SEN name)."""
    d = {
        "kinds": dict(zip(IN_NAMES, net.kinds, strict=False)),
        "groups": dict(zip(IN_NAMES, net.groups, strict=False)),
        "bas_level": {
            IN_NAMES[k]: float(net.bas_level[k]) for k, v in enumerate(net.kinds) if v == "bas"
        },
        "cpg": {},
        "omega": float(net.omega),
        "theta0": [float(v) for v in net.theta0],
        "tau_in": float(net.tau_in),
        "tau_mn": float(net.tau_mn),
        "bas_gated": bool(net.bas_gated),
        "ff_after": int(net.ff_after),
    }
    if net.base != "fbl":
        d["base"] = net.base
    for k in net.cpg_idx:
        d["cpg"][IN_NAMES[k]] = {
            "mean": float(net.cpg_mean[k]),
            "sd": float(net.cpg_sd[k]),
            "pattern_right": [float(v) for v in net.cpg_pattern[0, k]],
            "pattern_left": [float(v) for v in net.cpg_pattern[1, k]],
        }
    d.update(net.provenance)
    return d


def network_from_dict(d: dict, name: str, description: str = "", where: str = "network") -> Network:
    """A :class:`Network` from its JSON form; :class:`NetworkError` naming ``where`` and the
    offending entry."""
    if not isinstance(d, dict):
        raise NetworkError(f"{where}: 'network' must be an object, got {type(d).__name__}")

    def per_in(key, default):
        m = d.get(key, {})
        if not isinstance(m, dict):
            raise NetworkError(f"{where}: network.{key} must be an object {{IN name: value}}")
        bad = sorted(set(m) - set(IN_NAMES))
        if bad:
            raise NetworkError(
                f"{where}: network.{key}: unknown IN_SEN {bad}; known: {list(IN_NAMES)}"
            )
        return tuple(m.get(n, default) for n in IN_NAMES)

    kinds, groups = per_in("kinds", "sen"), per_in("groups", "sen")
    bas = per_in("bas_level", 0.0)
    cpg_d = d.get("cpg", {})
    if not isinstance(cpg_d, dict) or sorted(set(cpg_d) - set(IN_NAMES)):
        raise NetworkError(f"{where}: network.cpg must map IN_SEN names to patterns")
    missing = [n for n, k in zip(IN_NAMES, kinds, strict=False) if k == "cpg" and n not in cpg_d]
    if missing:
        raise NetworkError(f"{where}: IN_CPG {missing} need finite patterns in network.cpg")
    mean, sd = [0.0] * N_IN, [0.0] * N_IN
    pattern = None
    for name_k, entry in cpg_d.items():
        k = IN_NAMES.index(name_k)
        try:
            pr = np.asarray(entry["pattern_right"], float)
            pl = np.asarray(entry["pattern_left"], float)
            mean[k], sd[k] = float(entry["mean"]), float(entry["sd"])
        except (KeyError, TypeError, ValueError) as e:
            raise NetworkError(f"{where}: network.cpg[{name_k!r}] is malformed ({e})") from None
        if pattern is None:
            pattern = np.zeros((2, N_IN, pr.size))
        if pr.shape != (pattern.shape[2],) or pl.shape != pr.shape:
            raise NetworkError(f"{where}: network.cpg[{name_k!r}]: patterns of unequal lengths")
        pattern[0, k], pattern[1, k] = pr, pl
    known = {
        "kinds",
        "groups",
        "bas_level",
        "cpg",
        "omega",
        "theta0",
        "tau_in",
        "tau_mn",
        "bas_gated",
        "ff_after",
        "base",
    }
    try:
        return Network(
            name=name,
            kinds=kinds,
            groups=groups,
            bas_level=tuple(float(v) for v in bas),
            cpg_mean=tuple(mean),
            cpg_sd=tuple(sd),
            cpg_pattern=pattern,
            omega=float(d.get("omega", 0.85)),
            theta0=tuple(float(v) for v in d.get("theta0", (0.0, 0.5))),
            tau_in=float(d.get("tau_in", TAU_IN)),
            tau_mn=float(d.get("tau_mn", TAU_MN)),
            bas_gated=bool(d.get("bas_gated", True)),
            ff_after=int(d.get("ff_after", 3)),
            base=str(d.get("base", "fbl")),
            description=description,
            provenance={k: v for k, v in d.items() if k not in known},
        )
    except NetworkError as e:
        raise NetworkError(f"{where}: {e}") from None
    except (TypeError, ValueError) as e:
        raise NetworkError(f"{where}: network has a malformed value ({e})") from None
