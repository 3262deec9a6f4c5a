"""What a rollout records: a decimated time series, touchdown events and a summary.

All three are ``flax.struct`` pytrees with fixed shapes, so a batch of rollouts is a batch
of traces (leading population axis) and every measure of :mod:`jaxgait.analysis.measures` can be
computed in JAX, inside ``vmap``/``jit``.

Layout conventions used everywhere in jaxgait:
  * legs are indexed 0 = right, 1 = left;
  * ``qpos`` follows the MJCF: (root_x, root_z, trunk_pitch, hip_r, knee_r, ankle_r,
    hip_l, knee_l, ankle_l) in metres / radians, joint angles in the Winter convention
    (hip flexion +, knee flexion +, ankle dorsiflexion +, trunk forward lean +);
  * muscle arrays are (2, n_muscles) with the muscle order of the muscle table.
"""

from __future__ import annotations

import jax
from flax import struct


@struct.dataclass
class Trace:
    """Decimated samples, one row every ``log_every`` physics steps; shape (T, ...).

    Rows after the end of the rollout (fall or stop) repeat nothing meaningful and have
    ``alive == False``.

    Attributes:
      t: (T,) time [s].
      qpos: (T, nq) generalised positions [m, rad].
      com: (T, 2) whole-body centre of mass (x, z) [m].
      com_vel: (T, 2) centre-of-mass velocity [m/s].
      grf: (T, 2, 2) ground reaction force per leg (x, z) [N] (sum of heel and ball).
      stance: (T, 2) leg in stance (filtered ground contact), bool.
      act: (T, 2, M) muscle activations [0..1].
      stim: (T, 2, M) muscle stimulations [0..1].
      energy: (T,) cumulative metabolic energy [J].
      alive: (T,) the rollout was running at this sample, bool.
    """

    t: jax.Array
    qpos: jax.Array
    com: jax.Array
    com_vel: jax.Array
    grf: jax.Array
    stance: jax.Array
    act: jax.Array
    stim: jax.Array
    energy: jax.Array
    alive: jax.Array


@struct.dataclass
class Events:
    """Touchdown events detected at the physics rate; capacity E (fixed).

    Attributes:
      t: (E,) touchdown time [s].
      leg: (E,) leg that touched down (0 right, 1 left), int32.
      x_td: (E,) ankle x of the touching-down leg at touchdown [m].
      x_other: (E,) ankle x of the other leg at that instant [m].
      n: () number of recorded events (events beyond E are dropped; n keeps counting).
      peak_grf: (E,) largest vertical GRF of the stance begun at the event [N], taken at the
        physics step (the decimated trace misses millisecond transients such as a foot slap).
      peak_t: (E,) time of that peak after the touchdown [s].
      loading_rate: (E,) largest rise of the vertical GRF over one physics step during that
        stance, divided by the step [N/s].
      open: (2,) index of each leg's latest recorded event, whose stance is being measured
        (-1 before its first touchdown or when the buffer is full).

    The last four are None in event buffers made without them (e.g. by hand in tests); the
    measures that need them are then left out.
    """

    t: jax.Array
    leg: jax.Array
    x_td: jax.Array
    x_other: jax.Array
    n: jax.Array
    peak_grf: jax.Array | None = None
    peak_t: jax.Array | None = None
    loading_rate: jax.Array | None = None
    open: jax.Array | None = None


@struct.dataclass
class Summary:
    """End-of-rollout scalars.

    Attributes:
      duration: () time simulated before the end (fall or stopping criterion) [s].
      distance: () forward displacement of the centre of mass over that time [m].
      fell: () the rollout ended by a fall, bool.
      energy: () metabolic energy spent [J].
      trunk_lean_sum: () time integral of trunk pitch [rad s] (mean lean = sum / duration).
      mass: () body mass [kg].
      limit_torque_sq: () time integral of the summed squared soft-limit torques of the six
        leg joints [N^2 m^2 s] (Wang's J_L = this / duration).
    """

    duration: jax.Array
    distance: jax.Array
    fell: jax.Array
    energy: jax.Array
    trunk_lean_sum: jax.Array
    mass: jax.Array
    limit_torque_sq: jax.Array = 0.0
