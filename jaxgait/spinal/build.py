"""Build FBL-, 3FBL and 3FBL' (and FBL with the three control groups) from an FBL gait
(thesis 6.2.1, 6.2.2, 7.1.1.1, Fig. 6.2).

1. :func:`jaxgait.spinal.record.record` and :func:`~jaxgait.spinal.record.analyse`: the
   variability of every IN_SEN of the gait on flat ground;
2. :func:`select`: the IN_SEN to replace: the ``n_replace`` least variable (by the stability
   factor s) among the candidates (default: the muscle-feedback ones, MFF and MLF: the thesis
   removes 5 of its 13 per leg, "70 % of the sensory information coming from muscles"),
   optionally only those with s below ``s_max``;
3. :func:`build_network`: the model.  Groups (thesis 6.2.2): a replaced IN acting on GLU or
   HFL is in the ``cpg`` group, another replaced one in ``bas``, the rest in ``sen`` (FBL-
   has no CPG: all its replaced IN are ``bas``).  Kinds:

   * ``fbl_net``: every IN sensory (FBL reorganised, the groups only route the control);
   * ``fblminus``: every replaced IN basal (constant: the mean of the IN_SEN over its active
     phase, switched by its IN_SD gate; ``bas_gated=False`` makes it the mean over the whole
     cycle, always on);
   * ``3fbl``: replaced hip IN are CPG (the IN_SEN's nominal pattern per leg, its mean and SD,
     on the central clock at the gait's stride frequency), the others basal;
   * ``3fbl_prime``: as 3fbl, with the basal ones sensory again (still in group ``bas``).

4. :func:`model_preset`: the preset document (FBL parameters of the gait + the network, with
   the selection and the variability table as provenance), which ``evaluate``,
   ``robustness`` and ``train`` accept.
"""

from __future__ import annotations

import numpy as np

from jaxgait.control.fbl import GLU, HFL
from jaxgait.control.interneurons import IN_NAMES, IN_SEN, N_IN
from jaxgait.control.network_json import network_to_dict
from jaxgait.control.spinal import BASES, NETWORK_KINDS, Network
from jaxgait.spinal.record import Analysis, SpinalError

CANDIDATES = ("muscle", "replaceable")
#: Default CPG clock frequency [cycles/s] (thesis eq. 6.3).  A clock slower than the gait
#: restarts at each touchdown (thesis 6.3.2, case 1); ``omega=None`` takes the gait's own
#: stride frequency instead.
OMEGA = 0.85
#: The thesis's count of replaced IN_SEN per leg (7.1.1.1: "5 IN_SEN removed from the
#: initial 13").
N_REPLACE = 5
HIP_MUSCLES = (GLU, HFL)


def select(
    an: Analysis,
    n_replace: int | None = N_REPLACE,
    s_max: float | None = None,
    candidates: str = "muscle",
) -> list[str]:
    """Names of the IN_SEN to replace, least variable first (see the module docstring)."""
    if candidates not in CANDIDATES:
        raise SpinalError(f"candidates must be one of {CANDIDATES}, got {candidates!r}")
    pool = [i for i in IN_SEN if i.replaceable and (candidates != "muscle" or i.muscle_feedback)]
    if n_replace is not None and not (0 <= n_replace <= len(pool)):
        raise SpinalError(f"n_replace must lie in [0, {len(pool)}] ({candidates}), got {n_replace}")
    ranked = sorted(pool, key=lambda i: an.factor(i.name, "s"))
    if s_max is not None:
        ranked = [i for i in ranked if an.factor(i.name, "s") < s_max]
    if n_replace is not None:
        ranked = ranked[:n_replace]
    return [i.name for i in ranked]


def select_walking(
    an: Analysis,
    vec,
    source: str,
    n_replace: int = N_REPLACE,
    candidates: str = "muscle",
    kinds: tuple[str, ...] = ("fblminus", "3fbl"),
    check_s: float = 20.0,
    omega: float | None = OMEGA,
    log=print,
    base: str = "fbl",
    start: dict | None = None,
) -> tuple[list[str], list[dict]]:
    """Greedy selection with a walking check: go through the candidates least variable first
    (by s) and replace one when every model of ``kinds`` built with the replacements kept so
    far plus this one still walks ``check_s`` seconds on flat ground without falling; stop at
    ``n_replace``.  Returns (replaced names, one record per candidate tried)."""
    from jaxgait import evaluate
    from jaxgait.presets import forget_network

    order = select(an, None, None, candidates)
    kept, tried = [], []
    for nm in order:
        if len(kept) >= n_replace:
            break
        trial = kept + [nm]
        res = {"name": nm, "s": an.factor(nm, "s")}
        ok = True
        for kind in kinds:
            net = build_network(
                kind, an, trial, f"_check_{kind}_{len(tried)}", omega=omega, base=base
            )
            doc = model_preset(net, kind, vec, source, trial, an, {}, start)
            try:
                rep = evaluate.run(doc, duration=check_s).report
            finally:
                forget_network(net.name)
            res[kind] = {"walked_s": rep["duration_s"], "fell": rep["fell"]}
            ok = ok and not rep["fell"]
            if not ok:
                break
        res["kept"] = ok
        log(f"  {nm:<18} s={res['s']:.4f} " + ("kept" if ok else f"rejected ({res})"))
        tried.append(res)
        if ok:
            kept.append(nm)
    return kept, tried


def theta0_from(an: Analysis, omega: float) -> tuple[float, float]:
    """Clock phases at t = 0 so that each clock reaches 1 at its leg's first touchdown
    (clipped to [0, 0.99])."""
    return tuple(float(np.clip(1.0 - omega * t, 0.0, 0.99)) for t in an.first_td)


def build_network(
    kind: str,
    an: Analysis,
    replaced: list[str],
    name: str,
    *,
    bas_gated: bool = True,
    tau_in: float = 0.0,
    tau_mn: float = 0.0,
    omega: float | None = OMEGA,
    ff_after: int = 3,
    description: str = "",
    base: str = "fbl",
) -> Network:
    """The :class:`~jaxgait.control.spinal.Network` of ``kind`` (:data:`NETWORK_KINDS`);
    ``omega`` [cycles/s] is the clock's default (None: the gait's stride frequency)."""
    if kind not in NETWORK_KINDS:
        raise SpinalError(f"kind must be one of {NETWORK_KINDS}, got {kind!r}")
    unknown = sorted(set(replaced) - set(IN_NAMES))
    if unknown:
        raise SpinalError(f"unknown IN_SEN to replace: {unknown}")
    kinds, groups = ["sen"] * N_IN, ["sen"] * N_IN
    bas, mean, sd = [0.0] * N_IN, [0.0] * N_IN, [0.0] * N_IN
    pattern = np.zeros((2, N_IN, next(iter(an.per_leg.values()))[0].pattern.size))
    for k, i in enumerate(IN_SEN):
        if i.name not in replaced:
            continue
        hip = i.target in HIP_MUSCLES and kind != "fblminus"
        groups[k] = "cpg" if hip else "bas"
        legs = an.per_leg[i.name]
        bas[k] = float(np.mean([v.mean_active if bas_gated else v.mean for v in legs]))
        mean[k] = float(np.mean([v.mean for v in legs]))
        sd[k] = float(np.mean([v.sd for v in legs]))
        pattern[0, k], pattern[1, k] = legs[0].pattern, legs[1].pattern
        if kind == "fblminus" or (kind == "3fbl" and not hip):
            kinds[k] = "bas"
        elif kind in ("3fbl", "3fbl_prime") and hip:
            kinds[k] = "cpg"
    omega = 1.0 / an.stride_s if omega is None else float(omega)
    has_cpg = "cpg" in kinds
    return Network(
        name=name,
        kinds=tuple(kinds),
        groups=tuple(groups),
        bas_level=tuple(bas),
        cpg_mean=tuple(mean),
        cpg_sd=tuple(sd),
        cpg_pattern=pattern if has_cpg else None,
        omega=omega,
        theta0=theta0_from(an, omega),
        tau_in=tau_in,
        tau_mn=tau_mn,
        bas_gated=bas_gated,
        ff_after=ff_after,
        base=base,
        description=description,
    )


def model_preset(
    net: Network,
    kind: str,
    vec,
    source: str,
    replaced: list[str],
    an: Analysis,
    settings: dict,
    start: dict | None = None,
) -> dict:
    """The preset document of a built model (see the module docstring); ``start``: the
    source preset's start entries (``v0``, ``pose``), kept so the model starts as its gait."""
    table = BASES[net.base]
    params = dict(zip(table.names, (float(v) for v in np.asarray(vec, float)), strict=False))
    network = network_to_dict(net)
    network.update(
        kind=kind,
        source=source,
        selection={"replaced": list(replaced), **settings},
        stride_s=an.stride_s,
        stride_frequency=1.0 / an.stride_s,
        variability=an.table(),
    )
    return {
        "model": net.name,
        "table": table.name,
        "description": net.description,
        "params": params,
        "network": network,
        **(start or {}),
    }
