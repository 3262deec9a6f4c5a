"""Wang et al. 2012's 8-muscle reflex controller (ACM TOG 31(4), sections 4.1-4.3, Fig. 4).

Muscles per leg in :data:`jaxgait.muscles.mtu.MUSCLES8` order (HFL, GLU, HAM, VAS, GAS, SOL,
TA, RF) on :data:`jaxgait.muscles.mtu.WANG8`.  Parameters: :data:`~jaxgait.control.wang_params.
WANG` (66; its docstring gives the count and the initial values).

Building blocks (section 4.1), each a pure function below, with x(t - dt_m) the feature delayed
by the muscle's neural delay:

* positive force feedback  u^F = G F~(t - dt_m)                        (:func:`force_feedback`)
* positive length feedback u^L = {G (l~(t - dt_m) - H)}_+               (:func:`length_feedback`)
* muscle-driven PD         u^th = |{K (th(t - dt_m) - th_m) + D dth(t - dt_m)}_+-|
  with "+" when the muscle's torque opposes the direction of increasing th (an extensor and
  a flexion angle) and "-" otherwise (:func:`pd_feedback`).  The sign of each muscle is read
  from the moment-arm signs of the muscle table (:data:`PD_SIGN_HIP`, :data:`PD_SIGN_KNEE`).

States per leg (Fig. 4; :func:`update_phase`): stance -> swing initiation (SI: d > d_SI or
double stance, i.e. the other leg touched down) -> swing (contact lost) -> stance preparation
(SP: d < d_SP) -> stance (contact).  d = (x_CoM - x_ankle) / leg length.  SI and SP are latched:
a leg stays in SI until lift-off and in SP until touchdown; lift-off from stance and touchdown
from swing skip them.

Stance (section 4.2; :func:`stance_excitation`):
  SOL = p + u^F_SOL;  TA = p + u^L_TA - G_SOL,TA F~_SOL;  GAS = p + u^F_GAS;
  VAS = p + u^F_VAS + {k_th (th_k - th_k^off)}_{-, dth_k < 0};  RF = p;
  HAM, GLU, HFL = p + {u^Theta}_lead (trunk-pitch PD, only on the leading leg in double
  stance, no ground-load gating);
  SI adds -s_VAS, +s_RF, -s_GLU, +s_HFL.
Swing (section 4.3; :func:`swing_excitation`):
  TA = q + u^L_TA;  HAM = q + u^L_HAM;  GLU = q + u^L_GLU;
  HFL = q + u^L_HFL - u^L_HAM + k_Theta (Theta_lto - Theta_d), Theta_d = th_HFL;  others q;
  SP replaces VAS = q + u^{th_k}_VAS, GLU = q + u^{th_h}_GLU, HFL = q + u^{th_h}_HFL, with the
  shared hip target th_h = th_h0 + c_d d + c_v v (SIMBICON, :func:`balance_target`); d, v: the
  CoM's horizontal offset [m] and velocity [m/s] relative to the stance (other) leg's ankle.

Angles: Theta trunk pitch (forward lean +, the planar model's upper body; Wang's vector from
the pelvis CoM to the upper-body CoM), th_k knee flexion (0 straight), th_h thigh flexion from
the vertical (forward +: hip flexion minus trunk pitch; ``global_hip=False`` uses the hip joint
flexion instead).  The paper leaves the frame of th_h open; SIMBICON, whose law it uses,
controls the swing hip in the world frame.

Delays (section 4.1: "5 ms for MTUs connected to the hip, 20 ms for MTUs connected to the
ankle, 10 ms for the VAS and ground contact"): a muscle spanning the hip takes 5 ms (HFL, GLU,
HAM and RF), else one spanning the ankle 20 ms (GAS, SOL, TA), else 10 ms (VAS)
(:data:`MUSCLE_DELAY_GROUP`); the contact flags, and with them the whole state machine and the
lead leg, see 10 ms delayed sensors (so does d in the thresholds).  RF's laws are constants of
the state, so its own delay changes nothing.  Excitations are clipped to [0.01, 1] by the
muscle model.

Not Wang's: ``wang8_run_ld`` (:data:`WANG_RUN_LD_CONTROLLER`) adds a landing brake, two
feedforward TA excitations in late swing and just after touchdown (:func:`landing_brake`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.control.commands import Command
from jaxgait.control.delay import DelayLine, delay_init, delay_taps, steps_for
from jaxgait.control.interface import Controller, Sensors, com_over_other_ankle
from jaxgait.control.wang_params import INITIAL_ANGLE_NAMES, WANG, WANG_RUN, WANG_RUN_LD
from jaxgait.muscles.mtu import MUSCLES8, WANG8

HFL, GLU, HAM, VAS, GAS, SOL, TA, RF = range(8)
N_MUSCLES = len(MUSCLES8)

#: Leg states of Fig. 4.
STANCE, SI, SWING, SP = 0, 1, 2, 3

# per-leg sensor vector layout
W_F = slice(0, 8)  # F_mtu / F_max
W_L = slice(8, 16)  # l_ce / l_opt
W_CONTACT = 16  # 1 in stance (ground contact)
W_DS = 17  # 1 when the other leg touched down after this one (double stance, trailing)
W_TRUNK = 18  # Theta, trunk pitch [rad]
W_DTRUNK = 19  # its rate [rad/s]
W_KNEE = 20  # th_k, knee flexion [rad]
W_DKNEE = 21  # its rate [rad/s]
W_HIP = 22  # th_h, thigh flexion from the vertical (or hip flexion) [rad]
W_DHIP = 23  # its rate [rad/s]
W_THETA_TO = 24  # Theta at this leg's last lift-off [rad]
W_DLEG = 25  # d = (x_CoM - x_ankle) / leg length [-]
W_BAL_D = 26  # x_CoM - x_ankle of the other (stance) leg [m]
W_BAL_V = 27  # vx_CoM - vx_ankle of the other leg [m/s]
N_SENSORS = 28

#: PD sign per muscle for a hip-flexion-like angle (thigh flexion, or trunk lean, which hip
#: extensors of a stance leg pull back): +1 where the muscle extends the hip, -1 where it
#: flexes it, 0 where it does not span it (section 4.1's sign rule from the moment arms).
PD_SIGN_HIP = WANG8.sign[:, 0].copy()
#: PD sign per muscle for knee flexion: +1 for knee extensors (VAS, RF).
PD_SIGN_KNEE = WANG8.sign[:, 1].copy()
#: Delay group per muscle: 0 = hip (5 ms), 1 = knee (10 ms), 2 = ankle (20 ms).
MUSCLE_DELAY_GROUP = np.where(WANG8.spans[:, 0], 0, np.where(WANG8.spans[:, 2], 2, 1))


# ------------------------------------------------------------------------- building blocks
def force_feedback(gain, f_norm):
    """Positive force feedback u^F = G F~ [-] (section 4.1); F~ = F_mtu / F_max (delayed)."""
    return gain * f_norm


def length_feedback(gain, l_norm, offset):
    """Positive length feedback u^L = {G (l~ - H)}_+ [-] (section 4.1); l~ = l_ce / l_opt."""
    return jnp.maximum(gain * (l_norm - offset), 0.0)


def pd_feedback(k, d, theta, dtheta, target, sign):
    """Muscle-driven PD law u = |{K (theta - theta_m) + D dtheta}_+-| [-] (section 4.1).

    k [1/rad], d [s/rad], theta [rad], dtheta [rad/s], target theta_m [rad]; ``sign`` +1 takes
    the positive part (the muscle's torque opposes increasing theta), -1 the negative part's
    magnitude, 0 gives 0.  Broadcasts (e.g. over muscles).
    """
    x = k * (theta - target) + d * dtheta
    return jnp.maximum(sign * x, 0.0) * jnp.abs(sign)


def knee_overextension(k, theta_k, dtheta_k, offset):
    """VAS term {k (th_k - th_k^off)}_{-, dth_k < 0} [-] (section 4.2): negative (an inhibition)
    while the knee is straighter than the offset (th_k < th_k^off, flexion angles [rad]) and
    still extending (dth_k < 0 [rad/s]); 0 otherwise."""
    return jnp.where(dtheta_k < 0.0, jnp.minimum(k * (theta_k - offset), 0.0), 0.0)


def balance_target(theta0, c_d, c_v, d, v):
    """SIMBICON hip target th_h = th_h0 + c_d d + c_v v [rad] (Yin et al. 2007; Wang section
    4.3): d [m], v [m/s] the CoM's horizontal offset and velocity relative to the stance
    ankle; c_d [rad/m], c_v [rad s/m]."""
    return theta0 + c_d * d + c_v * v


def update_phase(prev, contact, ds, d, d_si, d_sp):
    """Next leg states (Fig. 4) from the previous ones, all (...,) int32 (STANCE, SI, SWING, SP).

    contact, ds: bool ground contact and "the other leg touched down after this one"; d:
    (x_CoM - x_ankle) / leg length; d_si, d_sp: the thresholds.  Contact decides stance vs
    swing (lift-off -> SWING, touchdown -> STANCE); then STANCE -> SI when d > d_si or ds, and
    SWING -> SP when d < d_sp (in the same step).
    """
    was_stance = (prev == STANCE) | (prev == SI)
    phase = jnp.where(
        contact, jnp.where(was_stance, prev, STANCE), jnp.where(was_stance, SWING, prev)
    )
    phase = jnp.where((phase == STANCE) & (ds | (d > d_si)), SI, phase)
    return jnp.where((phase == SWING) & (d < d_sp), SP, phase).astype(jnp.int32)


def _vec(p: dict, fmt: str, muscles, like) -> jax.Array:
    """(8,) parameters p[fmt.format(m)] for the named muscles, 0 elsewhere."""
    z = jnp.zeros_like(like)
    return jnp.stack([p[fmt.format(m)] if m in muscles else z for m in MUSCLES8])


# ------------------------------------------------------------------------- laws
def stance_excitation(p: dict, s: jax.Array, lead: jax.Array, si: jax.Array) -> jax.Array:
    """Stance excitations (rows, 8) from sensor rows s (rows, N_SENSORS), section 4.2.

    ``lead`` (rows,) bool: the trunk PD laws act (leading leg in double stance, or single
    stance); ``si`` (rows,) bool: swing initiation adds -s_VAS, +s_RF, -s_GLU, +s_HFL.
    """
    one = p["GF_SOL"]
    F, L = s[:, W_F], s[:, W_L]
    u = _vec(p, "p_{}", MUSCLES8, one) + force_feedback(
        _vec(p, "GF_{}", ("SOL", "GAS", "VAS"), one), F
    )
    trunk = pd_feedback(
        _vec(p, "K_{}", ("HAM", "GLU", "HFL"), one),
        _vec(p, "D_{}", ("HAM", "GLU", "HFL"), one),
        s[:, W_TRUNK, None],
        s[:, W_DTRUNK, None],
        _vec(p, "th_{}", ("HAM", "GLU", "HFL"), one),
        jnp.asarray(PD_SIGN_HIP, s.dtype),
    )
    u = u + jnp.where(lead[:, None], trunk, 0.0)
    ta = length_feedback(p["GL_TA"], L[:, TA], p["HL_TA"]) - p["GF_SOL_TA"] * F[:, SOL]
    vas = knee_overextension(p["k_knee"], s[:, W_KNEE], s[:, W_DKNEE], p["th_knee_off"])
    u = u.at[:, TA].add(ta).at[:, VAS].add(vas)
    z = jnp.zeros_like(one)
    s_add = jnp.stack([p["s_HFL"], -p["s_GLU"], z, -p["s_VAS"], z, z, z, p["s_RF"]])
    return u + jnp.where(si[:, None], s_add, 0.0)


def swing_excitation(p: dict, s: jax.Array, sp: jax.Array) -> jax.Array:
    """Swing excitations (rows, 8) from sensor rows s (rows, N_SENSORS), section 4.3.

    ``sp`` (rows,) bool: stance preparation replaces VAS, GLU and HFL by PD laws towards the
    knee target th_VAS_sp and the shared SIMBICON hip target.
    """
    one = p["GF_SOL"]
    q = _vec(p, "q_{}", MUSCLES8, one)
    swung = ("TA", "HAM", "GLU", "HFL")
    ul = length_feedback(
        _vec(p, "GL_{}_sw", swung, one), s[:, W_L], _vec(p, "HL_{}_sw", swung, one)
    )
    u = q + ul
    lean = p["k_lean"] * (s[:, W_THETA_TO] - p["th_HFL"])
    u = u.at[:, HFL].add(lean - ul[:, HAM])
    th_h = balance_target(p["th_hip0"], p["c_d"], p["c_v"], s[:, W_BAL_D], s[:, W_BAL_V])
    hip = pd_feedback(
        _vec(p, "K_{}_sp", ("GLU", "HFL"), one),
        _vec(p, "D_{}_sp", ("GLU", "HFL"), one),
        s[:, W_HIP, None],
        s[:, W_DHIP, None],
        th_h[:, None],
        jnp.asarray(PD_SIGN_HIP, s.dtype),
    )
    knee = pd_feedback(
        p["K_VAS_sp"],
        p["D_VAS_sp"],
        s[:, W_KNEE],
        s[:, W_DKNEE],
        p["th_VAS_sp"],
        float(PD_SIGN_KNEE[VAS]),
    )
    prep = u.at[:, VAS].set(q[VAS] + knee)
    prep = prep.at[:, GLU].set(q[GLU] + hip[:, GLU]).at[:, HFL].set(q[HFL] + hip[:, HFL])
    return jnp.where(sp[:, None], prep, u)


def wang_excitation(p: dict, s: jax.Array, phase: jax.Array, lead: jax.Array) -> jax.Array:
    """Excitations (rows, 8) of legs in the states ``phase`` (rows,) from sensor rows s."""
    in_stance = (phase == STANCE) | (phase == SI)
    st = stance_excitation(p, s, lead, phase == SI)
    sw = swing_excitation(p, s, phase == SP)
    return jnp.where(in_stance[:, None], st, sw)


def landing_brake(s_pre, d_pre, s_ld, t_ld, phase, dleg, t_stance):
    """TA excitation [-] of the landing brake (not Wang's), per leg: s_pre in swing (SWING or
    SP) once dleg = (x_CoM - x_ankle) / leg length < d_pre (the foot ahead of the CoM), s_ld
    while in stance (STANCE or SI) for at most t_ld [s] (t_stance [s]: the time since the
    leg's state became stance, counted from its first step, so ``t_ld`` = 0 gives none), else
    0.  A feedforward: the runners' forefoot comes down 20-26 ms after heel strike, as soon
    as TA's 20 ms length feedback (section 4.2) can act."""
    in_stance = (phase == STANCE) | (phase == SI)
    late_swing = ~in_stance & (dleg < d_pre)
    early = in_stance & (t_stance <= t_ld) & (t_ld > 0.0)
    return jnp.where(late_swing, s_pre, 0.0) + jnp.where(early, s_ld, 0.0)


# ------------------------------------------------------------------------- controller
@dataclass(frozen=True)
class WangSettings:
    """Static data: neural delays [s] of the (hip, knee, ankle) muscle groups and of ground
    contact (section 4.1), the frame of the stance-preparation hip angle, and whether the
    landing brake (:func:`landing_brake`; parameters s_TA_pre, d_TA_pre, s_TA_ld, T_ld)
    acts."""

    delays: tuple = (0.005, 0.010, 0.020)
    contact_delay: float = 0.010
    global_hip: bool = True
    landing_brake: bool = False


@struct.dataclass
class WangState:
    """Controller state: the sensor delay line, the leg states (2,) int32 (Fig. 4) and the
    number of steps (2,) int32 each leg has been in stance (STANCE or SI; 0 otherwise),
    counted only by a controller with the landing brake (0 in the others)."""

    lines: DelayLine
    phase: jax.Array
    n_stance: jax.Array


def packed_sensors(sens: Sensors, global_hip: bool = True) -> jax.Array:
    """The (2, N_SENSORS) per-leg sensor array (see the W_* layout) from the shared sensors."""
    dt = sens.f_norm.dtype
    one = jnp.ones((2,), dt)
    q_hip, dq_hip = jnp.pi - sens.phi[:, 0], -sens.dphi[:, 0]
    if global_hip:
        q_hip, dq_hip = q_hip - sens.trunk, dq_hip - sens.dtrunk
    d, v = com_over_other_ankle(sens)
    cols = [
        sens.stance.astype(dt),
        sens.double_support.astype(dt),
        sens.trunk * one,
        sens.dtrunk * one,
        jnp.pi - sens.phi[:, 1],
        -sens.dphi[:, 1],
        q_hip,
        dq_hip,
        sens.theta_to,
        sens.dleg,
        d,
        v,
    ]
    return jnp.concatenate([sens.f_norm, sens.l_norm, jnp.stack(cols, axis=1)], axis=1)


def _taps(settings: WangSettings, dt: float) -> tuple[int, ...]:
    return tuple(steps_for(d, dt) for d in settings.delays + (settings.contact_delay,))


def wang_init(ctrl: Controller, sens: Sensors, dt: float) -> WangState:
    """Delay line filled with the start sensors; stance legs in STANCE, the others in SWING."""
    x = packed_sensors(sens, ctrl.settings.global_hip)
    lines = delay_init(max(_taps(ctrl.settings, dt)), x)
    phase = jnp.where(sens.stance, STANCE, SWING).astype(jnp.int32)
    return WangState(lines=lines, phase=phase, n_stance=jnp.zeros((2,), jnp.int32))


def with_commands(p: dict, command: dict) -> dict:
    """``lean_offset`` [rad] added to the three trunk targets (HAM, GLU, HFL; Theta_d with HFL),
    ``hip_target_offset`` [rad] to the stance-preparation hip target th_h0."""
    lean = command["lean_offset"]
    return {
        **p,
        **{f"th_{m}": p[f"th_{m}"] + lean for m in ("HAM", "GLU", "HFL")},
        "th_hip0": p["th_hip0"] + command["hip_target_offset"],
    }


def wang_step(ctrl: Controller, p: dict, sens: Sensors, state: WangState, command: dict, dt):
    """One step: delayed sensors, state machine on the contact-delayed copy, then each muscle's
    excitation from its own delay group.  Returns (stim (2, 8), new state)."""
    p = with_commands(p, command)
    x = packed_sensors(sens, ctrl.settings.global_hip)
    outs, lines = delay_taps(state.lines, x, _taps(ctrl.settings, dt))  # (4, 2, S)
    c = outs[-1]
    contact, ds = c[:, W_CONTACT] > 0.5, c[:, W_DS] > 0.5
    phase = update_phase(state.phase, contact, ds, c[:, W_DLEG], p["d_SI"], p["d_SP"])
    lead = contact & ~ds
    g = outs[:-1]
    n = g.shape[0]
    stim = wang_excitation(
        p, g.reshape(n * 2, N_SENSORS), jnp.tile(phase, n), jnp.tile(lead, n)
    ).reshape(n, 2, N_MUSCLES)
    pick = jnp.asarray(MUSCLE_DELAY_GROUP)[None, None, :].repeat(2, 1)
    stim = jnp.take_along_axis(stim, pick, axis=0)[0]
    n_stance = state.n_stance  # counted only where the brake reads it
    if ctrl.settings.landing_brake:  # d and the states as the state machine sees them (10 ms)
        n_stance = jnp.where((phase == STANCE) | (phase == SI), n_stance + 1, 0)
        t_stance = n_stance * dt
        brake = landing_brake(
            p["s_TA_pre"], p["d_TA_pre"], p["s_TA_ld"], p["T_ld"], phase, c[:, W_DLEG], t_stance
        )
        stim = stim.at[:, TA].add(brake)
    return stim, WangState(lines=lines, phase=phase, n_stance=n_stance)


def wang_initial_offsets(ctrl: Controller, p: dict):
    """Start-posture offsets (7,) [rad] and start-speed offset [m/s] from the parameters."""
    return jnp.stack([p[n] for n in INITIAL_ANGLE_NAMES]), p["init_dv"]


#: Commands: a trunk-lean offset (as FBL's) and a hip-target offset (as FBL+'s).
COMMANDS: tuple[Command, ...] = (
    Command("lean_offset", 0.0, "rad", "added to the stance trunk targets th_HAM, th_GLU, th_HFL"),
    Command("hip_target_offset", 0.0, "rad", "added to th_hip0 (stance-preparation hip target)"),
)

#: Wang et al. 2012's controller on the 8-muscle leg.
WANG_CONTROLLER = Controller(
    name="wang8",
    table=WANG,
    n_muscles=N_MUSCLES,
    init=wang_init,
    step=wang_step,
    commands=COMMANDS,
    settings=WangSettings(),
    description="Wang et al. 2012 8-muscle reflex controller with SI/SP states and SIMBICON",
    initial_offsets=wang_initial_offsets,
)

#: The same controller with the running searches' wider ranges (:data:`WANG_RUN`): one step,
#: another parameter box.  A ``wang8`` preset runs unchanged on it (the same vector).
WANG_RUN_CONTROLLER = dataclasses.replace(
    WANG_CONTROLLER,
    name="wang8_run",
    table=WANG_RUN,
    description="wang8 with the running searches' wider ranges (GAS/SOL gains, hip target, "
    "start state)",
)

#: :data:`WANG_RUN_CONTROLLER` with the landing brake (:func:`landing_brake`) and its four
#: parameters appended to the table (:data:`~jaxgait.control.wang_params.WANG_RUN_LD`); with
#: them 0 it moves as ``wang8_run``.
WANG_RUN_LD_CONTROLLER = dataclasses.replace(
    WANG_RUN_CONTROLLER,
    name="wang8_run_ld",
    table=WANG_RUN_LD,
    settings=dataclasses.replace(WANG_RUN_CONTROLLER.settings, landing_brake=True),
    description="wang8_run with a landing brake: TA excitation in late swing and just after "
    "touchdown",
)
