"""Automatic speed control of a spinal-network model through its control vector.

The thesis steered 3FBL's speed and slope by hand and left an automatic controller as future
work (thesis 7.3, 8.2).  :func:`speed_controller` closes the loop inside the jitted step: it
wraps a network controller, takes the target speed v* [m/s] as its command and every step

0. limits the target to the speeds the model holds, v* <- clip(v*, v_min, v_max) (the
   defaults 0.2 and 3 m/s leave it alone; a preset sets them from ``spinal range``), and,
   with a rate limit a_max [m/s^2] (fixed data of the law, the preset's
   ``autopilot.target_rate``), its rate: the target the law uses moves towards v* at most
   a_max per second (a step of the command becomes a ramp; none by default);
1. filters the forward centre-of-mass velocity, v' = (v_com - v) / tau_v -> v [m/s];
2. integrates the error e = v* - v, I' = e, clamped to [-i_max, i_max] [m];
3. estimates the ground grade g [-] (rise over run) at every touchdown from the two
   contact points on the ground, the heel of the foot touching down and the ball of the
   other (stance) foot: g_td = (z_heel - z_ball) / (x_heel - x_ball), and
   g <- g + k_g (g_td - g) (a per-step filter of the chord of the terrain under the feet);
4. sets the basal offsets and the clock frequency (the slope rule: the thesis climbed by
   lowering omega and raising the basal offsets as the ground steepened, 7.3.1)
   O_INBAS = O_sched + k_ff (v* - v_ref) + k_p e + k_i I + k_sb g   [stim],
   O_INCPG = O_sched + k_o_cpg (v* - v_ref) + k_sc g                [stim],
   omega   = omega_sched + k_w (v* - v_ref) + k_sw g                [cycles/s],
   lean    = lean_sched + k_lean_v (v* - v_ref) + k_lean_g g          [rad],
   O_INSEN = O_sched + k_o_sen (v* - v_ref) + k_os_g g              [stim],
   A_INSEN = A_sched + k_a_sen (v* - v_ref) + k_as_g g              [-],
   and every other command c of the network c = c_sched + k_c (v* - v_ref) (the feedforward
   gains ``k_a_sen``, ``k_o_sen``, ``k_a_cpg``, ``k_a_bas``; 0 by default: a direction in C
   along which the speed changes), each clipped to the range the network declares
   (:func:`jaxgait.control.spinal.control_commands`);
   the feedforward term inverts the speed law of the systematic searches (thesis eq. 7.1:
   S = a1 O_INBAS + a2 omega + a3, so k_ff = 1 / a1 with k_w = 0);
5. runs the network with that control vector (the other commands as scheduled).

**Speed anchors (gain scheduling).**  A network's FBL parameters hold a walk over a narrow
band of speeds (about 0.3-0.5 m/s for 3FBL, whatever C does).  With ``anchors`` the wrapper
carries K parameter vectors p_k, each trained to hold its own constant target v_k (v_1 < ... <
v_K), and drives the network with their piecewise-linear interpolation at the law's target,

    p(v*) = p_k + (v* - v_k) / (v_{k+1} - v_k) (p_{k+1} - p_k)   for v_k <= v* <= v_{k+1},

held at p_1 below v_1 and at p_K above v_K (gain scheduling by the target speed; one
model, one command).  The interpolation follows the rate-limited target of
step 0, so a step of the command moves the network's gains along a ramp.

**Grade anchors.**  In the same way ``grade_anchors`` carry parameter vectors r_j trained to
hold a walk on a constant grade g_j (one of them at g = 0, the base r_0); the network then runs
with p(v*) + r(g_c) - r_0, r(g_c) their interpolation at the grade g_c felt through the
feet's lowest points: at every touchdown, the chord from the lower of the landing foot's heel
and ball to the lower of the other foot's, filtered as step 3's (:func:`contact_grade`).  Step
3's estimate reads the landing foot's heel, which a gait that lands flat-footed or on its
forefoot holds above the ground: on level ground it reads +0.05 to +0.09 for 3FBL, a bias
its trained slope rule has absorbed (its own gains keep that estimate); g_c reads about
0.01 there.
So the gains change with the ground as the trained climbers' do (the change measured at the
grade anchors' own target speed, added to the speed anchors' gains at any other).

The law's gains are its parameter table (:data:`AUTO_SPEED`, what an optimiser searches); the
network's own FBL parameters are fixed data of the wrapper, or, with ``network_in_table``,
entries of the table too (named ``net_`` + the FBL name, :func:`law_table`), so that one
search trains the network's gains and its command law together on several target speeds
(as Di Russo et al. 2023 trained one model over 0.3-1.9 m/s).  The wrapper's commands are
``v_target`` followed by the network's, so a schedule can move the target and still offset
any command of the network.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.control.commands import Command
from jaxgait.control.interface import Controller, Sensors
from jaxgait.control.speed_lean import filter_and_integrate
from jaxgait.core.params import ParamSpec, ParamTable

_L = "speed-law gain (automatic control)"
_FF = "feedforward per m/s of (v* - v_ref) on "

#: the feedforward gains on the other commands (step 4 of the module docstring)
FEEDFORWARD = {
    "A_INSEN": "k_a_sen",
    "O_INSEN": "k_o_sen",
    "A_INCPG": "k_a_cpg",
    "O_INCPG": "k_o_cpg",
    "A_INBAS": "k_a_bas",
    "lean_offset": "k_lean_v",
}
#: the slope rule's gains on the commands other than O_INBAS and omega (per unit grade)
SLOPE_RULE = {
    "O_INCPG": "k_sc",
    "lean_offset": "k_lean_g",
    "O_INSEN": "k_os_g",
    "A_INSEN": "k_as_g",
}

#: Gains of the speed law (see the module docstring).
AUTO_SPEED = ParamTable(
    "auto_speed",
    (
        ParamSpec("v_ref", 1.3, 0.5, 2.0, "speed of the network at the default C", "m/s"),
        ParamSpec("k_ff", 0.6, -2.0, 2.0, "feedforward O_INBAS per m/s (1 / a1 of eq. 7.1)"),
        ParamSpec("k_p", 0.05, 0.0, 1.0, _L + ": O_INBAS per m/s of error", "1/(m/s)"),
        ParamSpec("k_i", 0.02, 0.0, 1.0, _L + ": O_INBAS per m of integrated error", "1/m"),
        ParamSpec("k_w", 0.0, -2.0, 2.0, _L + ": omega per m/s of target", "1/m"),
        ParamSpec("tau_v", 1.0, 0.2, 3.0, "speed filter time constant (about a stride)", "s"),
        ParamSpec("i_max", 2.0, 0.1, 10.0, "anti-windup bound of the integral", "m"),
        ParamSpec("k_g", 0.5, 0.05, 1.0, "grade filter: fraction of a touchdown's estimate"),
        ParamSpec("k_sb", 0.0, -1.0, 1.0, "slope rule: O_INBAS per unit grade", "stim"),
        ParamSpec("k_sc", 0.0, -1.0, 1.0, "slope rule: O_INCPG per unit grade", "stim"),
        ParamSpec("k_sw", 0.0, -3.0, 3.0, "slope rule: omega per unit grade", "cycles/s"),
        ParamSpec("v_min", 0.2, 0.2, 3.0, "targets below are raised to this (speeds held)", "m/s"),
        ParamSpec("v_max", 3.0, 0.2, 3.0, "targets above are lowered to this (speeds held)", "m/s"),
        ParamSpec("k_a_sen", 0.0, -2.0, 2.0, _FF + "A_INSEN", "1/(m/s)"),
        ParamSpec("k_o_sen", 0.0, -0.5, 0.5, _FF + "O_INSEN", "1/(m/s)"),
        ParamSpec("k_a_cpg", 0.0, -2.0, 2.0, _FF + "A_INCPG", "1/(m/s)"),
        ParamSpec("k_o_cpg", 0.0, -0.5, 0.5, _FF + "O_INCPG", "1/(m/s)"),
        ParamSpec("k_a_bas", 0.0, -2.0, 2.0, _FF + "A_INBAS", "1/(m/s)"),
        ParamSpec("k_lean_v", 0.0, -0.5, 0.5, _FF + "lean_offset", "rad/(m/s)"),
        ParamSpec("k_lean_g", 0.0, -1.0, 1.0, "slope rule: lean_offset per unit grade", "rad"),
        ParamSpec("k_os_g", 0.0, -1.0, 1.0, "slope rule: O_INSEN per unit grade", "stim"),
        ParamSpec("k_as_g", 0.0, -5.0, 5.0, "slope rule: A_INSEN per unit grade"),
    ),
)

#: prefix of the network's own parameters in a table that holds them (:func:`law_table`)
NET_PREFIX = "net_"
#: name of the table of the law and its network's parameters (:func:`law_table`)
AUTO_SPEED_NET = AUTO_SPEED.name + "_net"


def law_table(inner_table: ParamTable) -> ParamTable:
    """:data:`AUTO_SPEED` followed by the network's parameters, each named ``net_`` + its
    name, with its start value, range and source (the table ``auto_speed_net``: the law and
    the network it drives trained together; a preset gives the values)."""
    net = tuple(
        ParamSpec(
            NET_PREFIX + s.name, s.init, s.lower, s.upper, f"network parameter ({s.source})", s.unit
        )
        for s in inner_table.specs
    )
    return ParamTable(AUTO_SPEED_NET, AUTO_SPEED.specs + net)


V_TARGET = Command("v_target", 1.3, "m/s", "target walking speed", 0.2, 3.0)


@dataclass(frozen=True, eq=False)
class AutoSettings:
    """Static data: the wrapped network controller and its fixed parameters (D,); the
    speed anchors' speeds (K,) [m/s] and parameter rows (K, D), and the grade anchors'
    grades (G,) and their rows less the level one's (G, D), or None without them."""

    inner: Controller
    inner_params: np.ndarray
    network_in_table: bool = False
    target_rate: float | None = None
    anchor_speeds: np.ndarray | None = None
    anchor_params: np.ndarray | None = None
    grade_points: np.ndarray | None = None
    grade_deltas: np.ndarray | None = None


@struct.dataclass
class AutoState:
    """The wrapped controller's state, the filtered speed v [m/s], the integral I [m],
    the grade estimate g [-], the rate-limited target [m/s] and the contact-point grade
    g_c [-] (:func:`contact_grade`; kept at 0 without grade anchors)."""

    inner: object
    v: jax.Array
    integral: jax.Array
    grade: jax.Array
    target: jax.Array
    ground: jax.Array


def _chord_at_touchdown(land, other, touchdown, grade, k_g):
    """The filtered grade of the chord from each leg's landing point ``land`` (2, 2) to the
    other leg's point ``other`` (2, 2) (x, z) [m]: g <- g + k_g (g_td - g) at each touchdown
    (dx kept at least 5 cm)."""
    dx = land[:, 0] - other[:, 0]
    dx = jnp.where(jnp.abs(dx) < 0.05, jnp.where(dx < 0, -0.05, 0.05), dx)
    g_td = (land[:, 1] - other[:, 1]) / dx
    for leg in range(2):
        grade = jnp.where(touchdown[leg], grade + k_g * (g_td[leg] - grade), grade)
    return grade


def grade_at_touchdown(feet, touchdown, grade, k_g):
    """Step 3 of the module docstring: the grade estimate after this step's touchdowns.

    feet: (4, 2) heel_r, ball_r, heel_l, ball_l (x, z) [m]; touchdown: (2,) bool."""
    heel = feet[jnp.array([0, 2])]  # (2, 2) heel of the leg touching down
    ball = feet[jnp.array([3, 1])]  # (2, 2) ball of the other leg
    return _chord_at_touchdown(heel, ball, touchdown, grade, k_g)


def contact_grade(feet, touchdown, grade, k_g):
    """The grade estimate of the grade anchors after this step's touchdowns: the chord from
    the lower (in z) of the landing foot's heel and ball to the lower of the other foot's,
    filtered as :func:`grade_at_touchdown` (feet as there)."""
    pts = feet.reshape(2, 2, 2)  # (leg, heel/ball, x/z)
    low = jnp.take_along_axis(pts, jnp.argmin(pts[:, :, 1], axis=1)[:, None, None], axis=1)[:, 0]
    return _chord_at_touchdown(low, low[::-1], touchdown, grade, k_g)


def target_speed(p: dict, v_target, previous=None, dt=0.0, a_max=None):
    """Step 0 of the module docstring: the target within the speeds the model holds and,
    given the law's ``previous`` target and a rate limit ``a_max`` [m/s^2], within
    a_max dt of it."""
    raw = jnp.clip(v_target, p["v_min"], p["v_max"])
    if previous is None or a_max is None:
        return raw
    return previous + jnp.clip(raw - previous, -a_max * dt, a_max * dt)


def speed_commands(p: dict, v_target, v, integral, sched: dict, commands, grade=0.0) -> dict:
    """The network's command dict from the law (step 4 of the module docstring)."""
    out = dict(sched)
    dv = v_target - p["v_ref"]
    e = v_target - v
    lim = {c.name: (c.lower, c.upper) for c in commands}
    if "O_INBAS" in out:
        o = out["O_INBAS"] + p["k_ff"] * dv + p["k_p"] * e + p["k_i"] * integral
        out["O_INBAS"] = jnp.clip(o + p["k_sb"] * grade, *lim["O_INBAS"])
    for c, k in FEEDFORWARD.items():
        if c in out:
            slope = p[SLOPE_RULE[c]] * grade if c in SLOPE_RULE else 0.0
            out[c] = jnp.clip(out[c] + p[k] * dv + slope, *lim[c])
    if "omega" in out:
        w = out["omega"] + p["k_w"] * dv + p["k_sw"] * grade
        out["omega"] = jnp.clip(w, *lim["omega"])
    return out


def anchored_params(v_target, speeds, params):
    """The network parameters at target ``v_target`` [m/s]: the piecewise-linear
    interpolation of the anchors' rows ``params`` (K, D) over their ``speeds`` (K,),
    increasing, held constant beyond the first and the last (module docstring)."""
    speeds = jnp.asarray(speeds, params.dtype)
    if speeds.shape[0] == 1:
        return params[0]
    v = jnp.clip(v_target, speeds[0], speeds[-1])
    k = jnp.clip(jnp.searchsorted(speeds, v, side="right") - 1, 0, speeds.shape[0] - 2)
    w = (v - speeds[k]) / (speeds[k + 1] - speeds[k])
    return params[k] + w * (params[k + 1] - params[k])


def auto_init(ctrl: Controller, sens: Sensors, dt: float) -> AutoState:
    inner = ctrl.settings.inner
    v0 = sens.com_vel[0]
    z = jnp.zeros_like(v0)
    inner_state = inner.init(inner, sens, dt)
    return AutoState(inner=inner_state, v=v0, integral=z, grade=z, target=v0, ground=z)


def auto_step(ctrl: Controller, p: dict, sens: Sensors, s: AutoState, command: dict, dt):
    """One step: the speed filter, the integral, the grade, the law, then the network."""
    st = ctrl.settings
    inner = st.inner
    a = 1.0 - jnp.exp(-dt / p["tau_v"])
    v_target = target_speed(p, command["v_target"], s.target, dt, st.target_rate)
    v, integral = filter_and_integrate(
        s.v, s.integral, sens.com_vel[0], v_target, a, dt, p["i_max"]
    )
    grade = grade_at_touchdown(sens.feet, sens.touchdown, s.grade, p["k_g"])
    sched = {c.name: command[c.name] for c in inner.commands}
    cmd = speed_commands(p, v_target, v, integral, sched, inner.commands, grade)
    if st.anchor_speeds is not None:
        rows = jnp.asarray(st.anchor_params, sens.f_norm.dtype)
        q = inner.table.unpack(anchored_params(v_target, st.anchor_speeds, rows))
    elif st.network_in_table:
        q = {n: p[NET_PREFIX + n] for n in inner.table.names}
    else:
        q = inner.table.unpack(jnp.asarray(st.inner_params, sens.f_norm.dtype))
    ground = s.ground  # read only by grade anchors: estimated only for them
    if st.grade_points is not None:
        ground = contact_grade(sens.feet, sens.touchdown, s.ground, p["k_g"])
        rows = jnp.asarray(st.grade_deltas, sens.f_norm.dtype)
        d = anchored_params(ground, st.grade_points, rows)
        q = {n: q[n] + d[i] for i, n in enumerate(inner.table.names)}
    stim, inner_state = inner.step(inner, q, sens, s.inner, cmd, dt)
    state = AutoState(
        inner=inner_state, v=v, integral=integral, grade=grade, target=v_target, ground=ground
    )
    return stim, state


def speed_controller(
    name: str,
    inner: Controller,
    inner_params,
    description: str = "",
    network_in_table: bool = False,
    target_rate: float | None = None,
    anchors=None,
    grade_anchors=None,
) -> Controller:
    """The closed-loop speed controller around the network controller ``inner`` driven by
    ``inner_params`` (its table's vector), or with ``network_in_table`` by the ``net_``
    entries of its own table (:func:`law_table`, ``inner_params`` their start values), or
    with ``anchors`` (a sequence of (v_k [m/s], parameter vector), distinct v_k) by their
    interpolation at the target (module docstring; ``inner_params`` then unused); with
    ``grade_anchors`` ((g_j, parameter vector) pairs, one at g = 0) the parameters move with
    the grade estimate by their interpolation less the g = 0 vector;
    ``target_rate`` [m/s^2] limits the rate of the target (step 0; None: no limit)."""
    if target_rate is not None and not target_rate > 0:
        raise ValueError(f"{name}: the target rate limit must be > 0 m/s^2, got {target_rate}")
    vec = np.asarray(inner_params, np.float64)
    if vec.shape != (inner.table.size,):
        raise ValueError(
            f"{name}: inner parameters need {inner.table.size} values, got {vec.shape}"
        )
    if anchors is not None and network_in_table:
        raise ValueError(f"{name}: speed anchors and network_in_table exclude each other")
    speeds, rows = _check_anchors(name, inner, anchors, "speed")
    grades, deltas = _check_anchors(name, inner, grade_anchors, "grade")
    if grades is not None:
        if 0.0 not in grades:
            raise ValueError(f"{name}: grade anchors need one at grade 0, got {grades.tolist()}")
        deltas = deltas - deltas[list(grades).index(0.0)]
    names = {c.name for c in inner.commands}
    if "O_INBAS" not in names:
        raise ValueError(f"{name}: the wrapped model {inner.name!r} has no O_INBAS command")
    return Controller(
        name=name,
        table=law_table(inner.table) if network_in_table else AUTO_SPEED,
        n_muscles=inner.n_muscles,
        init=auto_init,
        step=auto_step,
        commands=(V_TARGET,) + tuple(inner.commands),
        settings=AutoSettings(
            inner=inner,
            inner_params=vec,
            network_in_table=network_in_table,
            target_rate=None if target_rate is None else float(target_rate),
            anchor_speeds=speeds,
            anchor_params=rows,
            grade_points=grades,
            grade_deltas=deltas,
        ),
        description=description or f"automatic speed control of {inner.name}",
    )


def _check_anchors(name: str, inner: Controller, anchors, what: str):
    """(points (K,), rows (K, D)) of an ``anchors`` argument, checked; (None, None) without."""
    if anchors is None:
        return None, None
    anchors = list(anchors)
    if not anchors:
        raise ValueError(f"{name}: {what} anchors need at least one (point, parameters) pair")
    speeds = np.asarray([float(v) for v, _ in anchors], np.float64)
    rows = np.stack([np.asarray(q, np.float64) for _, q in anchors])
    if rows.shape != (len(anchors), inner.table.size):
        raise ValueError(
            f"{name}: each {what} anchor needs {inner.table.size} network parameters, "
            f"got rows of shape {rows.shape[1:]}"
        )
    if not np.all(np.isfinite(speeds)) or np.any(np.diff(np.sort(speeds)) <= 0):
        raise ValueError(f"{name}: {what} anchors must be distinct numbers, got {speeds.tolist()}")
    order = np.argsort(speeds)
    return speeds[order], rows[order]
