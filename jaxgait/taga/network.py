"""Neural rhythm generator of Taga et al. (1991): twelve Matsuoka neurons (eq. 5-6).

Neuron numbering follows the paper (1-based there, 0-based here):

  ====  =========================  ====  =========================
  1, 2  right hip flexor/extensor  7, 8  left knee flexor/extensor
  3, 4  left hip flexor/extensor   9, 10 right ankle flexor/extensor
  5, 6  right knee flexor/extensor 11, 12 left ankle flexor/extensor
  ====  =========================  ====  =========================

Every function here is pure and branch-free: the state is a :class:`NeuralState` pytree,
parameters are plain arrays, so a network can be vmapped over u0, time constants or
weights.  Time in seconds, the neural variables are dimensionless.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

N_NEURONS = 12

# Appendix D, the pairs (i, j) of the non-zero weights w_ij (neuron i receives y_j), 1-based.
FE_PAIRS = ((1, 2), (2, 1), (3, 4), (4, 3), (5, 6), (6, 5), (7, 8), (8, 7), (9, 10), (10, 9))
FE_PAIRS = FE_PAIRS + ((11, 12), (12, 11))
RL_PAIRS = ((1, 3), (3, 1), (2, 4), (4, 2))
HKA_PAIRS = ((6, 1), (6, 2), (8, 3), (8, 4), (10, 1), (10, 2), (12, 3), (12, 4))


def _mask(pairs) -> np.ndarray:
    m = np.zeros((N_NEURONS, N_NEURONS))
    for i, j in pairs:
        m[i - 1, j - 1] = 1.0
    return m


MASK_FE, MASK_RL, MASK_HKA = _mask(FE_PAIRS), _mask(RL_PAIRS), _mask(HKA_PAIRS)


@struct.dataclass
class NeuralState:
    """State of eq. 6.

    Attributes:
      u: (..., 12) inner states u_i.
      v: (..., 12) adaptation (self-inhibition) states v_i.
    """

    u: jax.Array
    v: jax.Array

    @property
    def y(self) -> jax.Array:
        """(..., 12) outputs y_i = f(u_i) = max(0, u_i) (eq. 6)."""
        return jnp.maximum(self.u, 0.0)


def zeros(dtype=jnp.float32) -> NeuralState:
    """Appendix E: all u_i = v_i = 0 (the text prints the dots of u and v; see README)."""
    z = jnp.zeros(N_NEURONS, dtype)
    return NeuralState(u=z, v=z)


def equilibrium(w, beta, u0, feed) -> NeuralState:
    """Stationary point of eq. 6 (du/dt = dv/dt = 0) for a fixed feedback, host NumPy.

    The literal reading of Appendix E ("du_i/dt, dv_i/dt = 0") as an initial state:
    v = y and (1 + beta) u_i - sum_j w_ij y_j = u0 + Feed_i on the active set y_i = u_i > 0,
    solved by active-set iteration.  (The default start is u = v = 0; see README.)
    """
    w = np.asarray(w, float)
    rhs = float(u0) + np.asarray(feed, float)
    active = np.ones(len(rhs), bool)
    u = np.zeros(len(rhs))
    for _ in range(4 * len(rhs)):
        a = np.eye(len(rhs)) - w * active[None, :] + beta * np.diag(active.astype(float))
        u = np.linalg.solve(a, rhs)
        new = u > 0
        if (new == active).all():
            break
        active = new
    y = np.maximum(u, 0.0)
    return NeuralState(u=jnp.asarray(u, jnp.float32), v=jnp.asarray(y, jnp.float32))


def weight_matrix(w_fe, w_rl, w_hka) -> jax.Array:
    """(12, 12) connection matrix W, W[i, j] = w_ij (Appendix D); the rest are zero."""
    return w_fe * MASK_FE + w_rl * MASK_RL + w_hka * MASK_HKA


def time_constants(tau_hip, tau_hip_adapt, tau_ka, tau_ka_adapt):
    """(12,) tau_i and tau'_i: neurons 1-4 (hips) and 5-12 (knees, ankles) (Appendix D)."""
    hip = jnp.arange(N_NEURONS) < 4
    return jnp.where(hip, tau_hip, tau_ka), jnp.where(hip, tau_hip_adapt, tau_ka_adapt)


def derivatives(state: NeuralState, w, tau, tau_adapt, beta, u0, feed):
    """Right-hand side of eq. 6.

    tau_i du_i/dt = -u_i + sum_j w_ij y_j - beta v_i + u0 + Feed_i,
    tau'_i dv_i/dt = -v_i + y_i.

    Args:
      state: neural state; w: (12, 12) weights; tau, tau_adapt: (12,) [s];
      beta, u0: scalars; feed: (12,) feedback Feed_i (0 for the isolated network).
    Returns:
      (du/dt, dv/dt), each (12,) [1/s].
    """
    y = state.y
    du = (-state.u + w @ y - beta * state.v + u0 + feed) / tau
    dv = (-state.v + y) / tau_adapt
    return du, dv


def euler_step(state: NeuralState, dt, w, tau, tau_adapt, beta, u0, feed) -> NeuralState:
    """One explicit-Euler step of eq. 6 of length ``dt`` [s]."""
    du, dv = derivatives(state, w, tau, tau_adapt, beta, u0, feed)
    return NeuralState(u=state.u + dt * du, v=state.v + dt * dv)


def rk4_step(state: NeuralState, dt, w, tau, tau_adapt, beta, u0, feed) -> NeuralState:
    """One classical Runge-Kutta step of eq. 6 with ``feed`` held over the step."""

    def f(s):
        return derivatives(s, w, tau, tau_adapt, beta, u0, feed)

    def add(s, d, h):
        return NeuralState(u=s.u + h * d[0], v=s.v + h * d[1])

    k1 = f(state)
    k2 = f(add(state, k1, dt / 2))
    k3 = f(add(state, k2, dt / 2))
    k4 = f(add(state, k3, dt))
    return NeuralState(
        u=state.u + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
        v=state.v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]),
    )


def feedback(th, dth_shank, contact, a) -> jax.Array:
    """Feedback signals Feed1-Feed12 of Appendix C.

    Args:
      th: (4,) segment angles from the downward vertical, + = backwards, in the order
        (right thigh, left thigh, right shank, left shank) = (x5, x8, x11, x14) - pi/2 [rad].
      dth_shank: (2,) right and left shank angular velocities dx11/dt, dx14/dt [rad/s].
      contact: (2,) somatic sense h(F_g2), h(F_g4) of the right and left ankle (0 or 1).
      a: (8,) gains a1..a8.
    Returns:
      (12,) Feed_i.  Feed6 is printed ``a5(x14 pi/2)h(F_g4)``; it is read as
      a5(x14 - pi/2)h(F_g4), the mirror of Feed5 as Feed8 is of Feed7.
    """
    tr, tl, sr, sl = th[0], th[1], th[2], th[3]
    cr, cl = contact[0], contact[1]
    a1, a2, a3, a4, a5, a6, a7, a8 = (a[k] for k in range(8))
    hip_r = a1 * tr - a2 * tl + a3 * sr * cr + a4 * cl
    hip_l = a1 * tl - a2 * tr + a3 * sl * cl + a4 * cr
    knee_r = -a5 * sl * cl  # Feed5 = a5 (pi/2 - x14) h(F_g4)
    knee_l = -a5 * sr * cr  # Feed7 = a5 (pi/2 - x11) h(F_g2)
    ank_r = -(a6 * sr * cr + a7 * sl * cl + a8 * dth_shank[0] * cr)  # Feed9
    ank_l = -(a6 * sl * cl + a7 * sr * cr + a8 * dth_shank[1] * cl)  # Feed11
    flex = jnp.stack([hip_r, hip_l, knee_r, knee_l, ank_r, ank_l])
    # odd neurons (flexors) get +flex, even neurons (extensors) the opposite signal
    return jnp.stack([flex, -flex], -1).reshape(N_NEURONS)


def torques(y, contact, p) -> jax.Array:
    """Joint torques T_r1..T_r6 of Appendix A [N m], + = extension.

    T_r1,2 (hips) = p_e^h y_ext - p_f^h y_flex, T_r3,4 (knees) likewise with p^k,
    T_r5,6 (ankles) = (p_e^a y_ext - p_f^a y_flex) h(F_g), only in ground contact.

    Args:
      y: (12,) neuron outputs; contact: (2,) right/left contact flags (0/1);
      p: (6,) gains (p_f^h, p_e^h, p_f^k, p_e^k, p_f^a, p_e^a).
    Returns:
      (6,) (T_r1, ..., T_r6) = (hip R, hip L, knee R, knee L, ankle R, ankle L).
    """
    yf, ye = y[0::2], y[1::2]  # (6,) flexor / extensor, order hipR hipL kneeR kneeL ankR ankL
    pf = jnp.stack([p[0], p[0], p[2], p[2], p[4], p[4]])
    pe = jnp.stack([p[1], p[1], p[3], p[3], p[5], p[5]])
    gate = jnp.concatenate([jnp.ones(4, y.dtype), contact.astype(y.dtype)])
    return (pe * ye - pf * yf) * gate


def isolated_rollout(state: NeuralState, n_steps: int, dt, w, tau, tau_adapt, beta, u0):
    """Integrate the isolated network (Feed_i = 0, Fig. 6B) with RK4.

    Returns:
      (final state, (n_steps, 12) inner states u sampled after every step).
    """
    feed = jnp.zeros(N_NEURONS, state.u.dtype)

    def body(s, _):
        s = rk4_step(s, dt, w, tau, tau_adapt, beta, u0, feed)
        return s, s.u

    return jax.lax.scan(body, state, None, length=n_steps)
