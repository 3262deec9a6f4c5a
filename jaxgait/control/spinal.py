"""The spinal network: SEN -> IN -> MN with feedforward interneurons (thesis 6.1-6.3).

One controller for FBL reorganised (every IN_SEN kept), FBL- (the least variable IN_SEN
replaced by constant basal interneurons IN_BAS), 3FBL (those acting on the hip muscles by
CPG interneurons IN_CPG, the rest by IN_BAS) and 3FBL' (3FBL with the IN_BAS put back as
IN_SEN, still governed by A/O_INBAS).  A model is a :class:`Network` (static data: which
interneuron is of which kind and in which control group, the basal levels, the CPG
patterns, the clock) given to :func:`spinal_controller`; the parameters are FBL's 28
(:data:`jaxgait.control.fbl.FBL`), so every FBL preset drives it.

Per step and leg, for each IN_SEN k (:mod:`jaxgait.control.interneurons`):

1. the sensors, delayed as FBL's (5 / 10 / 20 ms by the target muscle), give the raw term
   r_k; the SEN -> IN link is first order, y_k' = (r_k - y_k) / tau_in (thesis 6.1: "similar
   to equation 2.40"; ``tau_in`` = 0 passes r_k through);
2. the interneuron's activity x_k is y_k (IN_SEN), the constant level b_k (IN_BAS), or
   mu_k + sd_k a_k with a_k the AWO output (IN_CPG, :mod:`jaxgait.control.cpg`);
3. the control rule of its group g (thesis 6.2.2): out_k = O_g + A_g x_k, then the IN_SD gate
   (IN_SEN always; IN_BAS when ``bas_gated``; IN_CPG never: the pattern carries its phase);
4. the IN -> MN link is first order, z_k' = (out_k - z_k) / tau_mn, and each motoneuron sums
   its signed z_k plus the direct terms (S0 and the swing initiation).

Groups (thesis 6.2.2): ``sen`` holds the ground and trunk IN_SEN and the most variable muscle
ones; ``cpg`` the least variable muscle ones acting on GLU and HFL; ``bas`` the other least
variable muscle ones.  The links are integrated exactly over a step (y += (1 - e^(-dt/tau))
(r - y)), so any tau >= 0 is stable.  With tau_in = tau_mn = 0 and every IN_SEN kept, the
stimulation is FBL's (up to float rounding of the sums).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.control import cpg
from jaxgait.control.commands import Command
from jaxgait.control.delay import DelayLine, delay_taps
from jaxgait.control.fbl import (
    FBL,
    MUSCLE_DELAY_GROUP,
    N_MUSCLES,
    ReflexSettings,
    delay_taps_for,
    packed_sensors,
    reflex_init,
)
from jaxgait.control.fblplus import FBLPLUS, swing_end_pd, with_stance_end
from jaxgait.control.interface import Controller, Sensors
from jaxgait.control.interneurons import (
    IN_NAMES,
    N_IN,
    TARGETS,
    direct_terms,
    insen_inputs,
    motoneurons,
)

KINDS = ("sen", "bas", "cpg")
#: The reflex laws a network reorganises, with their parameter tables.
BASES = {"fbl": FBL, "fblplus": FBLPLUS}
GROUPS = ("sen", "cpg", "bas")
#: Default link time constants [s]: 0 passes the signal through (FBL's behaviour).
TAU_IN = 0.0
TAU_MN = 0.0
#: Per-IN delay group (that of its target muscle), static.
IN_DELAY_GROUP = MUSCLE_DELAY_GROUP[TARGETS]


class NetworkError(ValueError):
    """A network description is inconsistent (unknown names, kinds, missing patterns)."""


@dataclass(frozen=True, eq=False)
class Network:
    """Static description of a spinal network model.

    Attributes:
      name: model name.
      kinds: (K,) per IN_SEN of :data:`~jaxgait.control.interneurons.IN_SEN`: "sen", "bas"
        or "cpg".
      groups: (K,) its control group: "sen", "cpg" or "bas".
      bas_level: (K,) activity of each IN_BAS [stimulation] (unused for other kinds).
      cpg_mean, cpg_sd: (K,) mean and SD of the pattern each IN_CPG reproduces.
      cpg_pattern: (2, K, N) normalised nominal patterns per leg (zero mean, unit SD) at
        phases j/N from touchdown; rows of non-CPG IN are ignored.
      omega: default clock frequency [cycles/s] (the source gait's stride frequency).
      theta0: (2,) clock phases at t = 0 [cycles].
      tau_in, tau_mn: link time constants [s].
      bas_gated: IN_BAS are switched by their IN_SD gate (else constant over the cycle).
      ff_after: the feedforward IN (BAS, CPG) take over at this right-leg touchdown (count
        from the start; 0 = from t = 0); before it every IN is sensory, as in the thesis's
        own code, which starts on the full reflex and switches after a few cycles.  The
        clocks run (and restart at touchdowns) from the start.
      base: the reflex law the network reorganises: ``"fbl"`` (FBL's 28 parameters) or
        ``"fblplus"`` (FBL+'s 38: the same 15 IN_SEN, with FBL+'s stance end by CoM distance
        gating the stance-end IN and its swing-end PD rules added at the motoneurons as
        direct sensory pathways, like the swing initiation; thesis 2.1.3, 7.3.2's walk-run).
      description, provenance: free text / JSON-able data for listings and presets.
    """

    name: str
    kinds: tuple[str, ...] = ("sen",) * N_IN
    groups: tuple[str, ...] = ("sen",) * N_IN
    bas_level: tuple[float, ...] = (0.0,) * N_IN
    cpg_mean: tuple[float, ...] = (0.0,) * N_IN
    cpg_sd: tuple[float, ...] = (0.0,) * N_IN
    cpg_pattern: np.ndarray | None = None
    omega: float = 0.85
    theta0: tuple[float, float] = (0.0, 0.5)
    tau_in: float = TAU_IN
    tau_mn: float = TAU_MN
    bas_gated: bool = True
    ff_after: int = 3
    base: str = "fbl"
    description: str = ""
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.base not in BASES:
            raise NetworkError(f"network {self.name!r}: base {self.base!r} not in {tuple(BASES)}")
        for what, vals, allowed in (("kinds", self.kinds, KINDS), ("groups", self.groups, GROUPS)):
            if len(vals) != N_IN:
                raise NetworkError(
                    f"network {self.name!r}: {what} has {len(vals)} entries, need {N_IN}"
                )
            bad = sorted({v for v in vals if v not in allowed})
            if bad:
                raise NetworkError(f"network {self.name!r}: {what} {bad} not in {allowed}")
        for what in ("bas_level", "cpg_mean", "cpg_sd"):
            v = np.asarray(getattr(self, what), float)
            if v.shape != (N_IN,) or not np.all(np.isfinite(v)):
                raise NetworkError(f"network {self.name!r}: {what} must be {N_IN} finite numbers")
        if self.cpg_idx.size:
            pat = self.cpg_pattern
            if pat is None or np.shape(pat)[:2] != (2, N_IN) or not np.all(np.isfinite(pat)):
                raise NetworkError(
                    f"network {self.name!r}: IN_CPG {[IN_NAMES[k] for k in self.cpg_idx]} need "
                    f"finite patterns of shape (2, {N_IN}, N)"
                )
        if not (self.omega > 0 and self.tau_in >= 0 and self.tau_mn >= 0):
            raise NetworkError(f"network {self.name!r}: omega must be > 0 and taus >= 0")

    @property
    def cpg_idx(self) -> np.ndarray:
        return np.array([k for k, v in enumerate(self.kinds) if v == "cpg"], int)

    def members(self, kind: str) -> tuple[str, ...]:
        """Names of the IN of one kind."""
        return tuple(IN_NAMES[k] for k, v in enumerate(self.kinds) if v == kind)


#: A descending command beyond the thesis's C: an offset of the trunk-lean reference
#: theta_ref [rad] of the trunk-lean IN_SEN (TL, always sensory) and of the swing hip's lean
#: compensation, as FBL's ``lean_offset`` (:data:`jaxgait.control.fbl.LEAN_OFFSET`).  At its
#: default 0 the network is the thesis's.  Declared range [-0.2, 0.3] rad (-11 to 17 deg).
LEAN_COMMAND = Command(
    "lean_offset", 0.0, "rad", "added to theta_ref (trunk-lean reference)", -0.2, 0.3
)


def control_commands(groups, with_cpg: bool, omega: float) -> tuple[Command, ...]:
    """The control vector of a network (thesis 6.2.2): A/O of each group present, SEN
    first, then CPG, BAS, omega when the network has IN_CPG (defaults eq. 6.1-6.3:
    A = 1, O = 0), and last the trunk-lean offset :data:`LEAN_COMMAND` (0).  Declared
    ranges, for feedback laws: A in [0, 2], O in [-0.3, 0.3] [stim], omega in [0.3, 2]
    cycles/s (wider than every setting the thesis searched), lean in [-0.2, 0.3] rad."""
    out = []
    for g in GROUPS:
        if g == "sen" or g in groups:
            G = {"sen": "INSEN", "cpg": "INCPG", "bas": "INBAS"}[g]
            out.append(
                Command(f"A_{G}", 1.0, "-", f"scales the output of the {g} group's IN", 0.0, 2.0)
            )
            out.append(
                Command(f"O_{G}", 0.0, "stim", f"added to the {g} group's IN output", -0.3, 0.3)
            )
    if with_cpg:
        out.append(
            Command("omega", float(omega), "cycles/s", "CPG central-clock frequency", 0.3, 2.0)
        )
    out.append(LEAN_COMMAND)
    return tuple(out)


@dataclass(frozen=True, eq=False)
class SpinalSettings:
    """Static data of the spinal controller: FBL's delays plus the network and its arrays."""

    delays: tuple = ReflexSettings.delays
    network: Network | None = None
    kind: np.ndarray | None = None  # (K,) 0 sen, 1 bas, 2 cpg
    group: np.ndarray | None = None  # (K,) 0 sen, 1 cpg, 2 bas
    coef: np.ndarray | None = None  # (2, n_cpg, knots, 4) CPG spline coefficients


@struct.dataclass
class SpinalState:
    """Controller state: the sensor delay line, the link states, the clocks and the AWOs.

    Attributes:
      lines: FBL's delay line of packed sensors.
      y: (2, K) SEN -> IN link outputs (the IN_SEN inputs) [stim].
      out: (2, K) IN outputs after control and gating, this step [stim] (what the variability
        analysis reads).
      gate: (2, K) the IN_SD gates this step (1 on, 0 off).
      z: (2, K) IN -> MN link outputs [stim].
      theta: (2,) central-clock phases [cycles]; awo: (2, n_cpg) AWO outputs [-].
      steps: () right-leg touchdowns so far (int32): the feedforward IN act once it reaches
        the network's ``ff_after``.
    """

    lines: DelayLine
    y: jax.Array
    out: jax.Array
    gate: jax.Array
    z: jax.Array
    theta: jax.Array
    awo: jax.Array
    steps: jax.Array


def _alpha(tau: float, dt: float) -> float:
    return 1.0 if tau <= 0 else float(1.0 - np.exp(-dt / tau))


def _plus_rules(p, rows):
    """FBL+'s phases on (rows, S) delayed sensors: the stance-end sensors
    (:func:`jaxgait.control.fblplus.with_stance_end`) and the swing-end PD additions
    (rows, 7), zero outside swing end."""
    ended, swing_end = with_stance_end(p, rows)
    return ended, jnp.where(swing_end[:, None], swing_end_pd(p, rows), 0.0)


def _delayed_inputs(p, delayed, plus: bool = False):
    """IN_SEN inputs and gates of each IN from its target's delay group: delayed
    (3, 2, S) -> x, gate, direct (2, 7); with ``plus`` FBL+'s rules (:func:`_plus_rules`)."""
    g, legs, ns = delayed.shape
    rows = delayed.reshape(g * legs, ns)
    add = None
    if plus:
        rows, add = _plus_rules(p, rows)
        delayed = rows.reshape(g, legs, ns)
    x, gate = insen_inputs(p, rows)
    x, gate = x.reshape(g, legs, -1), gate.reshape(g, legs, -1)
    pick = jnp.asarray(IN_DELAY_GROUP)[None, None, :].repeat(legs, 1)
    x = jnp.take_along_axis(x, pick, axis=0)[0]
    gate = jnp.take_along_axis(gate, pick, axis=0)[0]
    d = direct_terms(p, rows)
    if add is not None:
        d = d + add
    d = d.reshape(g, legs, -1)
    mpick = jnp.asarray(MUSCLE_DELAY_GROUP)[None, None, :].repeat(legs, 1)
    return x, gate, jnp.take_along_axis(d, mpick, axis=0)[0]


def _controls(ctrl, command, dtype):
    """(A (K,), O (K,), omega) from the command dict; groups absent from it use 1 / 0."""
    net = ctrl.settings.network
    A, O = [], []
    for G in ("INSEN", "INCPG", "INBAS"):
        A.append(command.get(f"A_{G}", jnp.ones((), dtype)))
        O.append(command.get(f"O_{G}", jnp.zeros((), dtype)))
    group = jnp.asarray(ctrl.settings.group)
    A, O = jnp.stack(A).astype(dtype)[group], jnp.stack(O).astype(dtype)[group]
    return A, O, command.get("omega", jnp.asarray(net.omega, dtype))


def _activity(ctrl, y, awo, on, dtype):
    """(2, K) x_k by kind: y (SEN), the basal level (BAS), mu + sd a (CPG); every IN is
    sensory while ``on`` (the feedforward switch) is False."""
    st, net = ctrl.settings, ctrl.settings.network
    x = jnp.where(jnp.asarray(st.kind == 1), jnp.asarray(net.bas_level, dtype), y)
    idx = net.cpg_idx
    if idx.size:
        mu = jnp.asarray(np.asarray(net.cpg_mean)[idx], dtype)
        sd = jnp.asarray(np.asarray(net.cpg_sd)[idx], dtype)
        x = x.at[:, idx].set(mu + sd * awo)
    return jnp.where(on, x, y)


def _gated(ctrl, out, gate, on):
    st = ctrl.settings
    use = (st.kind == 0) | ((st.kind == 1) & st.network.bas_gated)
    return jnp.where(jnp.asarray(use) | ~on, out * gate, out)


def spinal_init(ctrl: Controller, sens: Sensors, dt: float) -> SpinalState:
    """Start state: the delay line filled with the start sensors, the links at 0 (with
    tau = 0 they take their input at the first step), the clocks at the network's theta0,
    the AWOs on their patterns."""
    lines = reflex_init(ctrl, sens, dt)
    dtype = sens.f_norm.dtype
    net, st = ctrl.settings.network, ctrl.settings
    theta = jnp.asarray(net.theta0, dtype)
    awo = jnp.zeros((2, net.cpg_idx.size), dtype)
    if net.cpg_idx.size:
        awo = cpg.spline_eval(jnp.asarray(st.coef, dtype), theta[:, None])[0]
    zeros = jnp.zeros((2, N_IN), dtype)
    return SpinalState(
        lines=lines,
        y=zeros,
        out=zeros,
        gate=zeros,
        z=zeros,
        theta=theta,
        awo=awo,
        steps=jnp.zeros((), jnp.int32),
    )


def spinal_step(ctrl: Controller, p: dict, sens: Sensors, s: SpinalState, command: dict, dt):
    """One step of the network: ``(stim (2, 7), new state)`` (see the module docstring)."""
    st, net = ctrl.settings, ctrl.settings.network
    dtype = sens.f_norm.dtype
    taps = delay_taps_for(st, dt)
    delayed, lines = delay_taps(s.lines, packed_sensors(sens), taps)
    if "lean_offset" in command:
        p = {**p, "theta_ref": p["theta_ref"] + command["lean_offset"]}
    r, gate, direct = _delayed_inputs(p, delayed, net.base == "fblplus")
    y = s.y + _alpha(net.tau_in, dt) * (r - s.y)
    A, O, omega = _controls(ctrl, command, dtype)
    theta, awo = s.theta, s.awo
    if net.cpg_idx.size:
        theta, rate = cpg.clock_step(s.theta, omega, sens.touchdown, dt)
        spline = cpg.PeriodicSpline(jnp.asarray(st.coef, dtype))
        awo = cpg.awo_step(s.awo, s.theta[:, None], rate[:, None], spline, dt)
    steps = s.steps + sens.touchdown[0].astype(jnp.int32)
    on = steps >= net.ff_after
    out = _gated(ctrl, O + A * _activity(ctrl, y, awo, on, dtype), gate, on)
    z = s.z + _alpha(net.tau_mn, dt) * (out - s.z)
    stim = motoneurons(direct, z)
    return stim, SpinalState(
        lines=lines, y=y, out=out, gate=gate, z=z, theta=theta, awo=awo, steps=steps
    )


def spinal_controller(net: Network, delays: tuple = ReflexSettings.delays) -> Controller:
    """The controller of a network (FBL's parameter table, the network's control vector)."""
    kind = np.array([KINDS.index(k) for k in net.kinds])
    group = np.array([GROUPS.index(g) for g in net.groups])
    idx = net.cpg_idx
    coef = None
    if idx.size:
        coef = cpg.periodic_spline(np.asarray(net.cpg_pattern, float)[:, idx])
    commands = control_commands(set(net.groups), bool(idx.size), net.omega)
    settings = SpinalSettings(delays=delays, network=net, kind=kind, group=group, coef=coef)
    return Controller(
        name=net.name,
        table=BASES[net.base],
        n_muscles=N_MUSCLES,
        init=spinal_init,
        step=spinal_step,
        commands=commands,
        settings=settings,
        description=net.description or "spinal network (thesis ch. 6)",
    )


#: Kinds of network model built from a gait (:mod:`jaxgait.spinal.build`).
NETWORK_KINDS = ("fbl_net", "fblminus", "3fbl", "3fbl_prime")

#: FBL reorganised as a spinal network (every IN_SEN kept, one control group, fast links).
FBL_NET = Network(
    name="fbl_net",
    description="FBL reorganised as SEN -> IN_SEN -> MN (thesis 6.1), control vector A/O_INSEN",
)
#: FBL+ reorganised the same way (its extra phase rules as direct sensory pathways).
FBLPLUS_NET = Network(
    name="fblplus_net",
    base="fblplus",
    description="FBL+ reorganised as SEN -> IN_SEN -> MN (thesis 6.1, 2.1.3), control A/O_INSEN",
)
