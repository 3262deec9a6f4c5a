"""Parameter table of Wang et al. 2012's 8-muscle controller (:mod:`jaxgait.control.wang`).

Wang et al. 2012 (section 5) count 56 parameters of the muscle control laws, 30 for stance and
26 for swing: each force feedback law u^F has one (G), each length feedback law u^L two (G, H)
and each muscle-driven PD law u^theta three (K, D, theta).  The table below has exactly that
split; where the paper's equations leave a choice, the count decides it:

* stance (30) = 8 pre-stimulations p_m + force gains of SOL, GAS, VAS (3) + TA length law (2)
  + a separate gain of TA's suppression by SOL force (1; Geyer & Herr's G_SOL,TA, written
  "-u_SOL^F" in the paper) + VAS knee over-extension law k_theta, theta_k^off (2) + three
  trunk PD laws with their own targets (HAM, GLU, HFL: 9) + swing-initiation excitations
  s_VAS, s_RF, s_GLU, s_HFL (4) + threshold d_SI (1);
* swing (26) = 8 pre-stimulations q_m + length laws of TA, HAM, GLU, HFL (8; HFL's "-u_HAM^L"
  is HAM's own swing law, no extra parameter) + k_Theta (1; its reference Theta_d is the
  stance HFL target theta_HFL, as the paper says) + stance-preparation PD laws of VAS (3) and
  of GLU and HFL (K, D each: 4) + their shared hip target theta_h0 (1) + threshold d_SP (1).

Then the SIMBICON balance gains c_d, c_v (section 4.3) and the planar initial state
(offsets of the start posture and speed: Wang optimises 33 initial-state values of his 3-D
model, section 5): 66 parameters in all.

Initial values.  Wang initialises the walking controller "based on hand-tuned values for 2D
walking from Geyer and Herr [2010]" and gives the numbers only in his supplement, which is not
available here.  So every gain with a Geyer-Herr counterpart starts from Geyer's own Simulink
values (the "G" family of ``geyer_reference.md`` 2c, as :data:`jaxgait.control.fbl.FBL`),
in the same normalised units (force per F_max, length per l_opt, angles in rad).  Laws
without a counterpart start at values given, with their reason, in their source strings
("chosen" where Geyer-Herr offer nothing to copy).  Two of Wang's changes cannot keep
Geyer-Herr's values for every muscle at once: swing HAM now has a length law that also
inhibits HFL, and it starts as Geyer's HAM->HFL inhibition (gain 4), so HFL's swing law is
Geyer-Herr's and HAM's own late-swing excitation is larger than Geyer-Herr's force feedback
gave; the double-stance VAS inhibition by contralateral load becomes the constant s_VAS.
The thresholds start beyond the reach of a walking gait (d_SI = 0.6, d_SP = -0.6 leg lengths;
at touchdown the ankles are roughly 0.3-0.4 leg lengths from the CoM), so the start gait
enters swing initiation by double stance only, as Geyer-Herr's does, and never enters stance
preparation.  Ranges are wide margins around these values (the paper gives none).

Angle conventions (see :mod:`jaxgait.control.wang`): Theta trunk pitch (forward lean +),
theta_k knee flexion (0 straight, bent +), theta_h thigh flexion from the vertical (forward +).
"""

from __future__ import annotations

from jaxgait.core.params import ParamSpec, ParamTable, widened

_G = "Geyer nms_model_ControlInit.m (geyer_reference 2c, G family)"
_W = "Wang 2012 section 4"
_NEW = "no Geyer-Herr counterpart; chosen"

_KP = 1.9099  # Geyer's trunk PD gain k_p = 1 / 30 deg [1/rad]
_KD = 0.2  # Geyer's trunk PD gain k_d [s/rad]
_TH_REF = 0.1047  # Geyer's trunk lean reference theta_ref = 6 deg [rad]


def _pre(prefix: str, phase: str, values: dict[str, tuple[float, str]]) -> tuple[ParamSpec, ...]:
    return tuple(
        ParamSpec(f"{prefix}_{m}", v, 0.0, 0.3, f"{phase} pre-stimulation of {m}: {src}")
        for m, (v, src) in values.items()
    )


#: Stance-phase parameters (30), Wang 2012 section 4.2.
STANCE_SPECS: tuple[ParamSpec, ...] = _pre(
    "p",
    "stance",
    {
        "HFL": (0.05, "S0_BAL " + _G),
        "GLU": (0.05, "S0_BAL " + _G),
        "HAM": (0.05, "S0_BAL " + _G),
        "VAS": (0.08, "S0_VAS " + _G),
        "GAS": (0.01, "S0 " + _G),
        "SOL": (0.01, "S0 " + _G),
        "TA": (0.01, "S0 " + _G),
        "RF": (0.01, "Geyer-Herr have no RF; 'close to zero' (" + _W + ".2)"),
    },
) + (
    ParamSpec("GF_SOL", 1.2, 0.0, 3.0, "SOL force feedback G_SOL; " + _G),
    ParamSpec("GF_GAS", 1.1, 0.0, 3.0, "GAS force feedback G_GAS; " + _G),
    ParamSpec("GF_VAS", 1.2, 0.0, 3.0, "VAS force feedback G_VAS; " + _G),
    ParamSpec("GF_SOL_TA", 0.4, 0.0, 2.0, "TA suppression by SOL force G_SOL,TA; " + _G),
    ParamSpec("GL_TA", 1.1, 0.0, 5.0, "TA length feedback G_TA; " + _G),
    ParamSpec("HL_TA", 0.72, 0.4, 1.2, "TA length offset l_off,TA = 1 - 0.5 w; " + _G, "l_opt"),
    ParamSpec("k_knee", 2.0, 0.0, 5.0, "VAS knee over-extension gain k_phi; " + _G, "1/rad"),
    ParamSpec(
        "th_knee_off",
        0.1745,
        0.0,
        0.5,
        "knee offset 10 deg flexion (phi_k,off 170 deg); " + _G,
        "rad",
    ),
    ParamSpec("K_HAM", _KP, 0.0, 5.0, "HAM trunk PD k_p; " + _G, "1/rad"),
    ParamSpec("D_HAM", _KD, 0.0, 1.0, "HAM trunk PD k_d; " + _G, "s/rad"),
    ParamSpec("th_HAM", _TH_REF, -0.2, 0.4, "HAM trunk target theta_ref 6 deg; " + _G, "rad"),
    ParamSpec("K_GLU", 0.7 * _KP, 0.0, 5.0, "GLU trunk PD 0.7 k_p (GLU = 0.7 HAM); " + _G, "1/rad"),
    ParamSpec("D_GLU", 0.7 * _KD, 0.0, 1.0, "GLU trunk PD 0.7 k_d (GLU = 0.7 HAM); " + _G, "s/rad"),
    ParamSpec("th_GLU", _TH_REF, -0.2, 0.4, "GLU trunk target theta_ref 6 deg; " + _G, "rad"),
    ParamSpec("K_HFL", _KP, 0.0, 5.0, "HFL trunk PD k_p; " + _G, "1/rad"),
    ParamSpec("D_HFL", _KD, 0.0, 1.0, "HFL trunk PD k_d; " + _G, "s/rad"),
    ParamSpec(
        "th_HFL",
        _TH_REF,
        -0.2,
        0.4,
        "HFL trunk target = Theta_d of swing; theta_ref " + _G,
        "rad",
    ),
    ParamSpec(
        "s_VAS",
        0.6,
        0.0,
        1.0,
        "swing-initiation VAS inhibition; ~ k_bw x 0.5 BW, the mean contralateral-load "
        "inhibition of Geyer-Herr's VAS in double support (" + _G + "); range " + _W + ".2",
    ),
    ParamSpec("s_RF", 0.0, 0.0, 1.0, "swing-initiation RF excitation; Geyer-Herr have no RF"),
    ParamSpec("s_GLU", 0.25, 0.0, 1.0, "swing-initiation GLU inhibition, Delta S; " + _G),
    ParamSpec("s_HFL", 0.25, 0.0, 1.0, "swing-initiation HFL excitation, Delta S; " + _G),
    ParamSpec(
        "d_SI",
        0.6,
        0.0,
        1.0,
        "swing initiation when (x_CoM - x_ankle)/leg > d_SI; beyond walking reach (" + _NEW + ")",
        "leg lengths",
    ),
)

#: Swing-phase parameters (26), Wang 2012 section 4.3.
SWING_SPECS: tuple[ParamSpec, ...] = _pre(
    "q",
    "swing",
    {m: (0.01, "S0 " + _G) for m in ("HFL", "GLU", "HAM")}
    | {"VAS": (0.01, "Geyer's swing VAS 0, clipped to the 0.01 floor; " + _G)}
    | {m: (0.01, "S0 " + _G) for m in ("GAS", "SOL", "TA")}
    | {"RF": (0.01, "Geyer-Herr have no RF; 'close to zero'")},
) + (
    ParamSpec("GL_TA_sw", 1.1, 0.0, 5.0, "swing TA length feedback G_TA; " + _G),
    ParamSpec("HL_TA_sw", 0.72, 0.4, 1.2, "swing TA length offset l_off,TA; " + _G, "l_opt"),
    ParamSpec(
        "GL_HAM_sw",
        4.0,
        0.0,
        8.0,
        "swing HAM length feedback; Geyer's HAM->HFL inhibition G_HAMHFL (the same law "
        "inhibits HFL) " + _G,
    ),
    ParamSpec("HL_HAM_sw", 0.85, 0.4, 1.2, "swing HAM length offset l_off,HAM; " + _G, "l_opt"),
    ParamSpec(
        "GL_GLU_sw", 0.5, 0.0, 3.0, "swing GLU length feedback; Geyer's swing GLU gain " + _G
    ),
    ParamSpec(
        "HL_GLU_sw",
        1.0,
        0.4,
        1.5,
        "swing GLU length offset, optimal length (" + _NEW + ")",
        "l_opt",
    ),
    ParamSpec("GL_HFL_sw", 0.5, 0.0, 3.0, "swing HFL length feedback G_HFL; " + _G),
    ParamSpec("HL_HFL_sw", 0.65, 0.3, 1.2, "swing HFL length offset l_off,HFL; " + _G, "l_opt"),
    ParamSpec("k_lean", 1.1459, 0.0, 3.0, "swing HFL lean gain k_Theta 2 %/deg; " + _G, "1/rad"),
    ParamSpec(
        "K_VAS_sp", _KP, 0.0, 5.0, "stance-prep. VAS knee PD; 1/30 deg (" + _NEW + ")", "1/rad"
    ),
    ParamSpec(
        "D_VAS_sp", _KD, 0.0, 1.0, "stance-prep. VAS knee PD; as k_d (" + _NEW + ")", "s/rad"
    ),
    ParamSpec(
        "th_VAS_sp",
        0.0873,
        0.0,
        1.0,
        "stance-prep. knee target 5 deg flexion (Geyer's start knee 175 deg)",
        "rad",
    ),
    ParamSpec(
        "K_GLU_sp", _KP, 0.0, 5.0, "stance-prep. GLU hip PD; 1/30 deg (" + _NEW + ")", "1/rad"
    ),
    ParamSpec("D_GLU_sp", _KD, 0.0, 1.0, "stance-prep. GLU hip PD; as k_d (" + _NEW + ")", "s/rad"),
    ParamSpec(
        "K_HFL_sp", _KP, 0.0, 5.0, "stance-prep. HFL hip PD; 1/30 deg (" + _NEW + ")", "1/rad"
    ),
    ParamSpec("D_HFL_sp", _KD, 0.0, 1.0, "stance-prep. HFL hip PD; as k_d (" + _NEW + ")", "s/rad"),
    ParamSpec(
        "th_hip0",
        0.4,
        -0.2,
        1.2,
        "shared hip target theta_h0 (thigh flexion from vertical), ~23 deg, the thigh at "
        "human heel strike (" + _NEW + ")",
        "rad",
    ),
    ParamSpec(
        "d_SP",
        -0.6,
        -1.0,
        0.0,
        "stance preparation when (x_CoM - x_ankle)/leg < d_SP; beyond walking reach (" + _NEW + ")",
        "leg lengths",
    ),
)

#: SIMBICON balance feedback on the hip target, theta_h = theta_h0 + c_d d + c_v v (Yin et al.
#: 2007; Wang 2012 section 4.3).  0 = off, as Geyer-Herr's walker has none.
BALANCE_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("c_d", 0.0, 0.0, 2.0, "SIMBICON position gain; 0 = off (" + _NEW + ")", "rad/m"),
    ParamSpec("c_v", 0.0, 0.0, 1.0, "SIMBICON velocity gain; 0 = off (" + _NEW + ")", "rad s/m"),
)

_INIT = "offset on the simulator's start pose (SimConfig.pose); Wang 2012 section 5 optimises "
_INIT += "the initial state"
#: Planar initial state: offsets of the start posture (Winter convention: trunk pitch, then
#: hip, knee, ankle of the stance leg and of the swing leg) and of the start speed.
INITIAL_SPECS: tuple[ParamSpec, ...] = tuple(
    ParamSpec(f"init_{n}", 0.0, -0.2, 0.2, f"{n.replace('_', ' ')} angle {_INIT}", "rad")
    for n in ("trunk", "hip_st", "knee_st", "ankle_st", "hip_sw", "knee_sw", "ankle_sw")
) + (ParamSpec("init_dv", 0.0, -0.5, 0.5, "forward speed offset on SimConfig.v0; " + _INIT, "m/s"),)

#: Names of the initial-state angle offsets, in :attr:`Controller.initial_offsets` order.
INITIAL_ANGLE_NAMES: tuple[str, ...] = tuple(s.name for s in INITIAL_SPECS[:7])

#: The 66 parameters: 30 stance, 26 swing, 2 balance, 8 initial state.
WANG = ParamTable("wang8", STANCE_SPECS + SWING_SPECS + BALANCE_SPECS + INITIAL_SPECS)

#: Ranges of :data:`WANG_RUN`, widened where the searched runners sat at a bound of
#: :data:`WANG` (``wang_run_2p5``: GF_SOL 2.94 of 3, th_hip0 1.17 of 1.2 rad, HL_HAM_sw 1.19
#: of 1.2, init_dv 0.49 of 0.5 m/s, init_trunk -0.19 of -0.2 rad; the 3.7 m/s runner
#: ``wang_run_3p7``: GL_HFL_sw 3.07 of 3).
RUN_RANGES: dict[str, tuple[float, float]] = {
    "GF_SOL": (0.0, 5.0),  # Wang doubles Geyer's 1.2 for running; 5 leaves room above 2.4
    "GF_GAS": (0.0, 5.0),  # as GF_SOL (Geyer 1.1, doubled 2.2)
    "HL_HAM_sw": (0.4, 1.5),
    "th_hip0": (-0.2, 1.6),
    "init_trunk": (-0.5, 0.2),
    "init_knee_sw": (-0.2, 1.5),  # a running swing knee bends to about 100 deg
    "init_dv": (-0.5, 2.5),  # the 3.78 m/s runner wang_run_3p75 starts 1.66 m/s above v0
    "GL_HFL_sw": (0.0, 5.0),  # the swing hip flexor's length gain of the faster runners
}


#: :data:`WANG` with :data:`RUN_RANGES`: the table of the running searches (model
#: ``wang8_run``); the same names in the same order, so a ``wang8`` vector is a ``wang8_run``
#: vector.
WANG_RUN = widened(WANG, "wang8_run", RUN_RANGES, "; range widened for running (wang8_run)")


#: A landing brake (not Wang's; :data:`WANG_RUN_LD`, model ``wang8_run_ld``): TA excitation
#: added as a feedforward in late swing (once the foot is ahead of the CoM by -d_TA_pre leg
#: lengths) and for the first T_ld of stance, so that the dorsiflexor is active when the foot's
#: second point comes down.  Wang's stance TA law is a length feedback delayed 20 ms, the state
#: machine sees contact 10 ms late, and the runners' forefoot slaps down 20-26 ms after heel
#: strike (experiments/running/landing), so neither a feedback of the ankle nor an excitation
#: begun at (sensed) touchdown is active in time; stance preparation (d < d_SP) is not entered
#: by the runners (their d_SP of -0.71 to -0.85 leg lengths lies beyond where the swing foot
#: lands).  s_TA_pre = s_TA_ld = 0 = off: a ``wang8_run`` vector moves alike on
#: ``wang8_run_ld``.
LANDING_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("s_TA_pre", 0.0, 0.0, 1.0, "TA excitation added in late swing (landing brake)", "-"),
    ParamSpec(
        "d_TA_pre",
        -0.3,
        -1.0,
        0.5,
        "late swing for s_TA_pre: (x_CoM - x_ankle)/leg < d_TA_pre; chosen: the foot 0.3 leg "
        "lengths ahead of the CoM",
        "leg lengths",
    ),
    ParamSpec(
        "s_TA_ld",
        0.0,
        0.0,
        1.0,
        "TA excitation added in the first T_ld of stance (landing brake)",
        "-",
    ),
    ParamSpec("T_ld", 0.0, 0.0, 0.1, "duration of the stance TA excitation s_TA_ld", "s"),
)

#: :data:`WANG_RUN` and the landing brake's four parameters (:data:`LANDING_SPECS`), last.
WANG_RUN_LD = ParamTable("wang8_run_ld", WANG_RUN.specs + LANDING_SPECS)
