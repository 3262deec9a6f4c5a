"""The paper's own equations of motion (eq. 1-4, Appendices A and B) as a cross-check.

An independent, MJX-free implementation of the Taga et al. (1991) biped in the paper's
14 maximal coordinates

  x = (x1, x2 hip; x3, x4, x5 right thigh centre and angle; x6, x7, x8 left thigh;
       x9, x10, x11 right shank; x12, x13, x14 left shank),

with the 8 hinge forces F solved from the twice-differentiated constraints (eq. 3):
x'' = P F + Q, C x'' = D, F = (C P)^-1 (D - C Q).  Bodies and neurons are advanced
together by the classical fourth-order Runge-Kutta method (the paper used the closely
related Runge-Kutta-Gill scheme); which ankles are in contact, and their rest points, are
decided once per step from the state at its start.

Used by the tests (MJX body vs. these equations) and by the README's integration-scheme
comparison; the simulator itself is :mod:`jaxgait.taga.sim`.  Units SI, angles rad.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.taga import network
from jaxgait.taga.model import TagaParams
from jaxgait.world.terrain import Terrain

# Appendix D geometry (the MJCF holds the same numbers; the test checks they agree)
M, M1, L1, M2, L2, G = 48.0, 7.0, 0.5, 4.0, 0.6, 9.8
I1, I2 = M1 * L1**2 / 12, M2 * L2**2 / 12


def appendix_e() -> np.ndarray:
    """Appendix E positions x1..x14 (the velocities are zero)."""
    x = np.zeros(14)
    x[0], x[1] = 0.0, 1.09
    x[4] = x[10] = 0.45 * np.pi
    x[7] = x[13] = 0.57 * np.pi
    _fill_links(x)
    return x


def _fill_links(x):
    c, s = np.cos, np.sin
    x[2], x[3] = x[0] + L1 / 2 * c(x[4]), x[1] - L1 / 2 * s(x[4])
    x[5], x[6] = x[0] + L1 / 2 * c(x[7]), x[1] - L1 / 2 * s(x[7])
    x[8] = x[0] + L1 * c(x[4]) + L2 / 2 * c(x[10])
    x[9] = x[1] - L1 * s(x[4]) - L2 / 2 * s(x[10])
    x[11] = x[0] + L1 * c(x[7]) + L2 / 2 * c(x[13])
    x[12] = x[1] - L1 * s(x[7]) - L2 / 2 * s(x[13])


def from_qpos(qpos, qvel=None) -> tuple[np.ndarray, np.ndarray]:
    """Maximal coordinates (x, dx/dt) of an MJCF state (qpos = x_hip, z_hip, hip_r,
    knee_r, hip_l, knee_l)."""
    q = np.asarray(qpos, float)
    dq = np.zeros(6) if qvel is None else np.asarray(qvel, float)

    def pos(q):
        x = np.zeros(14)
        x[0], x[1] = q[0], q[1]
        x[4], x[10] = np.pi / 2 + q[2], np.pi / 2 + q[2] + q[3]
        x[7], x[13] = np.pi / 2 + q[4], np.pi / 2 + q[4] + q[5]
        _fill_links(x)
        return x

    eps = 1e-6
    jac = np.stack([(pos(q + eps * e) - pos(q - eps * e)) / (2 * eps) for e in np.eye(6)], -1)
    return pos(q), jac @ dq


def ankles(x, xd):
    """Ankle positions (2, 2) and velocities (2, 2), rows right / left (Appendix A)."""
    p = jnp.stack(
        [
            jnp.stack([x[8] + L2 / 2 * jnp.cos(x[10]), x[9] - L2 / 2 * jnp.sin(x[10])]),
            jnp.stack([x[11] + L2 / 2 * jnp.cos(x[13]), x[12] - L2 / 2 * jnp.sin(x[13])]),
        ]
    )
    v = jnp.stack(
        [
            jnp.stack(
                [xd[8] - L2 / 2 * jnp.sin(x[10]) * xd[10], xd[9] - L2 / 2 * jnp.cos(x[10]) * xd[10]]
            ),
            jnp.stack(
                [
                    xd[11] - L2 / 2 * jnp.sin(x[13]) * xd[13],
                    xd[12] - L2 / 2 * jnp.cos(x[13]) * xd[13],
                ]
            ),
        ]
    )
    return p, v


def accelerations(x, xd, tau, fg):
    """Eq. 4: x'' from the segment torques tau (4,) on (x5, x8, x11, x14) and the ankle
    forces fg (2, 2) = ((F_g1, F_g2), (F_g3, F_g4))."""
    s, c = jnp.sin, jnp.cos
    z = jnp.zeros(())
    # P (14 x 8): rows of Appendix A, columns F1..F8
    h1, h2 = L1 / 2, L2 / 2
    P = jnp.zeros((14, 8))
    P = P.at[0, 0].set(1 / M).at[0, 2].set(1 / M).at[1, 1].set(1 / M).at[1, 3].set(1 / M)
    P = P.at[2, 0].set(-1 / M1).at[2, 4].set(1 / M1).at[3, 1].set(-1 / M1).at[3, 5].set(1 / M1)
    P = P.at[4, 0].set(-h1 * s(x[4]) / I1).at[4, 1].set(-h1 * c(x[4]) / I1)
    P = P.at[4, 4].set(-h1 * s(x[4]) / I1).at[4, 5].set(-h1 * c(x[4]) / I1)
    P = P.at[5, 2].set(-1 / M1).at[5, 6].set(1 / M1).at[6, 3].set(-1 / M1).at[6, 7].set(1 / M1)
    P = P.at[7, 2].set(-h1 * s(x[7]) / I1).at[7, 3].set(-h1 * c(x[7]) / I1)
    P = P.at[7, 6].set(-h1 * s(x[7]) / I1).at[7, 7].set(-h1 * c(x[7]) / I1)
    P = P.at[8, 4].set(-1 / M2).at[9, 5].set(-1 / M2)
    P = P.at[10, 4].set(-h2 * s(x[10]) / I2).at[10, 5].set(-h2 * c(x[10]) / I2)
    P = P.at[11, 6].set(-1 / M2).at[12, 7].set(-1 / M2)
    P = P.at[13, 6].set(-h2 * s(x[13]) / I2).at[13, 7].set(-h2 * c(x[13]) / I2)
    g1, g2, g3, g4 = fg[0, 0], fg[0, 1], fg[1, 0], fg[1, 1]
    Q = jnp.stack(
        [
            z,
            -G,
            z,
            -G,
            tau[0] / I1,
            z,
            -G,
            tau[1] / I1,
            g1 / M2,
            g2 / M2 - G,
            (-h2 * (g1 * s(x[10]) + g2 * c(x[10])) + tau[2]) / I2,
            g3 / M2,
            g4 / M2 - G,
            (-h2 * (g3 * s(x[13]) + g4 * c(x[13])) + tau[3]) / I2,
        ]
    )
    # C (8 x 14), D (8,): Appendix B differentiated twice
    C = jnp.zeros((8, 14))
    C = C.at[0, 0].set(1).at[0, 2].set(-1).at[0, 4].set(-h1 * s(x[4]))
    C = C.at[1, 1].set(1).at[1, 3].set(-1).at[1, 4].set(-h1 * c(x[4]))
    C = C.at[2, 0].set(1).at[2, 5].set(-1).at[2, 7].set(-h1 * s(x[7]))
    C = C.at[3, 1].set(1).at[3, 6].set(-1).at[3, 7].set(-h1 * c(x[7]))
    C = C.at[4, 2].set(1).at[4, 4].set(-h1 * s(x[4])).at[4, 8].set(-1).at[4, 10].set(-h2 * s(x[10]))
    C = C.at[5, 3].set(1).at[5, 4].set(-h1 * c(x[4])).at[5, 9].set(-1).at[5, 10].set(-h2 * c(x[10]))
    C = (
        C.at[6, 5]
        .set(1)
        .at[6, 7]
        .set(-h1 * s(x[7]))
        .at[6, 11]
        .set(-1)
        .at[6, 13]
        .set(-h2 * s(x[13]))
    )
    C = (
        C.at[7, 6]
        .set(1)
        .at[7, 7]
        .set(-h1 * c(x[7]))
        .at[7, 12]
        .set(-1)
        .at[7, 13]
        .set(-h2 * c(x[13]))
    )
    w5, w8, w11, w14 = xd[4] ** 2, xd[7] ** 2, xd[10] ** 2, xd[13] ** 2
    D = jnp.stack(
        [
            h1 * c(x[4]) * w5,
            -h1 * s(x[4]) * w5,
            h1 * c(x[7]) * w8,
            -h1 * s(x[7]) * w8,
            h1 * c(x[4]) * w5 + h2 * c(x[10]) * w11,
            -h1 * s(x[4]) * w5 - h2 * s(x[10]) * w11,
            h1 * c(x[7]) * w8 + h2 * c(x[13]) * w14,
            -h1 * s(x[7]) * w8 - h2 * s(x[13]) * w14,
        ]
    )
    F = jnp.linalg.solve(C @ P, D - C @ Q)  # eq. 3
    return P @ F + Q  # eq. 4


def make_rollout(params: TagaParams, terrain: Terrain, dt: float, n_steps: int):
    """A jitted RK4 rollout of eqs. 4 and 6 from (x, xd, u, v); returns a function
    ``run(x, xd, u, v) -> (x, xd, u, v, xs)`` with xs (n_steps, 14) positions."""
    from jaxgait.taga import ground
    from jaxgait.taga.model import joint_torques

    w = network.weight_matrix(params.w_fe, params.w_rl, params.w_hka)
    tau_n, tau_a = network.time_constants(
        params.tau_hip, params.tau_hip_adapt, params.tau_ka, params.tau_ka_adapt
    )

    def deriv(x, xd, u, v, gstate):
        pos, vel = ankles(x, xd)
        below = gstate.below  # contact set held over the step (see module docstring)
        rest = gstate.rest
        fx = -params.k_g * (pos[:, 0] - rest[:, 0]) - params.b_g * vel[:, 0]
        fy = -params.k_g * (pos[:, 1] - rest[:, 1]) + params.b_g * jnp.maximum(-vel[:, 1], 0.0)
        fg = jnp.where(below[:, None], jnp.stack([fx, fy], -1), 0.0)
        cont = ground.somatic_sense(fg)
        th = jnp.stack([x[4], x[7], x[10], x[13]]) - jnp.pi / 2
        dth = jnp.stack([xd[4], xd[7], xd[10], xd[13]])
        ns = network.NeuralState(u=u, v=v)
        tr = network.torques(ns.y, cont, params.p)
        tau = joint_torques(th, dth, tr, params)
        feed = params.feedback_gain * network.feedback(th, dth[2:], cont, params.a)
        du, dv = network.derivatives(ns, w, tau_n, tau_a, params.beta, params.u0, feed)
        return xd, accelerations(x, xd, tau, fg), du, dv

    def step(carry, _):
        x, xd, u, v, gs = carry
        pos, vel = ankles(x, xd)
        _, gs, _ = ground.contact_forces(pos, vel, gs, terrain, params.k_g, params.b_g)
        k1 = deriv(x, xd, u, v, gs)
        s2 = [a + dt / 2 * b for a, b in zip((x, xd, u, v), k1, strict=True)]
        k2 = deriv(*s2, gs)
        s3 = [a + dt / 2 * b for a, b in zip((x, xd, u, v), k2, strict=True)]
        k3 = deriv(*s3, gs)
        s4 = [a + dt * b for a, b in zip((x, xd, u, v), k3, strict=True)]
        k4 = deriv(*s4, gs)
        new = [
            a + dt / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
            for a, b1, b2, b3, b4 in zip((x, xd, u, v), k1, k2, k3, k4, strict=True)
        ]
        return (*new, gs), new[0]

    @jax.jit
    def run(x, xd, u, v):
        gs = ground.initial(x.dtype)
        (x, xd, u, v, _), xs = jax.lax.scan(step, (x, xd, u, v, gs), None, length=n_steps)
        return x, xd, u, v, xs

    return run
