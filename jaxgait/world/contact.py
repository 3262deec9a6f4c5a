"""Geyer & Herr 2010 ground contact: nonlinear spring-damper with stick/slip friction.

Computed by jaxgait (MuJoCo's constraint solver is off) for every contact point (heel and
ball of each foot) against a :class:`~jaxgait.world.terrain.Terrain` height function.  Laws as in
Geyer's model (``geyer_reference.md`` §3e), written in the local ground frame (normal n,
tangent t) so that they hold on slopes:

* normal:   F_n = k_n d (1 - v_n / v_n_max), kept >= 0         d = penetration > 0
* stiction: F_t = -k_t s (1 + sgn(s) v_t / v_t_max)           s = tangential offset of the
                                                               point from its anchor
* sliding:  F_t = -sgn(v_t) mu_slide F_n
* stick -> slide when |F_t,stick| > mu_stick F_n;  slide -> stick when |v_t| < v_limit.

Each law is "spring + velocity damping", F = a - c v, with a damping coefficient that grows
with the penetration (c = k_n d / v_n_max).  A foot's contact points see an effective mass
of a fraction of a kilogram, so an explicit step would need dt << 0.1 ms; the simulator
therefore resolves the damping of all contact rows linearly-implicitly (see
:mod:`jaxgait.sim.rows`).  This module gives the rows (a, c, direction) and, from the row
velocities the solver settles on, the final forces, slide flags and anchors.
Units: N, m, m/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.world.terrain import Terrain, normal_of_slope


@dataclass(frozen=True)
class ContactParams:
    """Geyer ground-contact constants (G column of geyer_reference.md §3e)."""

    k_n: float = 78480.0  # N/m, M g / 0.01 m with M = 80 kg
    v_n_max: float = 0.03  # m/s
    k_t: float = 7848.0  # N/m, M g / 0.1 m
    v_t_max: float = 0.03  # m/s
    mu_slide: float = 0.8
    mu_stick: float = 0.9
    v_limit: float = 0.01  # m/s, slide -> stick


@struct.dataclass
class ContactState:
    """Per contact point (P,): anchor position (x, z) [m] and sliding flag."""

    anchor: jax.Array  # (P, 2)
    sliding: jax.Array  # (P,) bool


@struct.dataclass
class ContactRows:
    """Row form of the contact laws for P points (all (P,) unless noted).

    normal/tangent: (P, 2) unit world directions; a_n, c_n and a_t, c_t: spring force [N]
    and damping [N s/m] of the normal and tangential rows, F = a - c v; the tangential row
    of a sliding point carries the Coulomb force in a_t and c_t = 0.
    """

    normal: jax.Array
    tangent: jax.Array
    in_contact: jax.Array
    depth: jax.Array
    a_n: jax.Array
    c_n: jax.Array
    a_t: jax.Array
    c_t: jax.Array
    slide_prev: jax.Array


def init_contact(points: jax.Array) -> ContactState:
    """Anchors at the current point positions, all sticking."""
    return ContactState(anchor=points, sliding=jnp.zeros(points.shape[:-1], bool))


def contact_rows(
    cp: ContactParams, terrain: Terrain, state: ContactState, pos: jax.Array, vel: jax.Array
) -> ContactRows:
    """Spring and damping terms of every contact row at positions/velocities (P, 2)."""
    x, z = pos[..., 0], pos[..., 1]
    h, slope = terrain.height_slope(x)
    n = normal_of_slope(slope)
    t = jnp.stack([n[..., 1], -n[..., 0]], -1)  # forward tangent
    depth = (h - z) * n[..., 1]  # distance below the ground line along n
    in_contact = depth > 0.0
    d = jnp.maximum(depth, 0.0)
    a_n = cp.k_n * d
    c_n = cp.k_n * d / cp.v_n_max
    s = ((pos - state.anchor) * t).sum(-1)
    slide_prev = state.sliding & in_contact
    # sticking: spring to the anchor with Geyer's displacement-scaled damping;
    # sliding: a damper strong enough to stop sub-v_limit motion, capped at mu F_n below
    # (so the friction never reverses the motion within a step).
    a_t = jnp.where(slide_prev, 0.0, -cp.k_t * s)
    c_t = jnp.where(slide_prev, cp.mu_slide * a_n / cp.v_limit, cp.k_t * jnp.abs(s) / cp.v_t_max)
    zero = jnp.zeros_like(a_n)
    return ContactRows(
        normal=n,
        tangent=t,
        in_contact=in_contact,
        depth=depth,
        a_n=jnp.where(in_contact, a_n, zero),
        c_n=jnp.where(in_contact, c_n, zero),
        a_t=jnp.where(in_contact, a_t, zero),
        c_t=jnp.where(in_contact, c_t, zero),
        slide_prev=slide_prev,
    )


def contact_finalize(
    cp: ContactParams, rows: ContactRows, state: ContactState, pos, y_n, y_t
) -> tuple[jax.Array, ContactState, jax.Array]:
    """Forces from the row velocities (y_n, y_t) used for the damping (P,).

    The normal force is kept >= 0; a sticking point whose force exceeds mu_stick F_n starts
    sliding, and a sliding point's friction is capped at mu_slide F_n (both only shrink the
    force the implicit solve found, keeping its direction); a sliding point sticks again
    once its velocity is below v_limit.

    Returns world forces (P, 2) [N], the next contact state and the normal forces (P,).
    """
    f_n = jnp.maximum(rows.a_n - rows.c_n * y_n, 0.0)
    f_t = rows.a_t - rows.c_t * y_t
    slip = (~rows.slide_prev) & (jnp.abs(f_t) > cp.mu_stick * f_n)
    sliding = rows.slide_prev | slip
    cap = cp.mu_slide * f_n
    f_t = jnp.where(sliding, jnp.clip(f_t, -cap, cap), f_t)
    f_t = jnp.where(rows.in_contact, f_t, 0.0)
    force = f_n[..., None] * rows.normal + f_t[..., None] * rows.tangent
    sliding = sliding & rows.in_contact & ~(rows.slide_prev & (jnp.abs(y_t) < cp.v_limit))
    # anchor kept while sticking in contact; otherwise it follows the point (projected on
    # the ground), so touchdown and re-sticking anchor where the point is.
    ground_pt = pos + jnp.maximum(rows.depth, 0.0)[..., None] * rows.normal
    keep = rows.in_contact & ~sliding & ~rows.slide_prev
    anchor = jnp.where(keep[..., None], state.anchor, ground_pt)
    return force, ContactState(anchor=anchor, sliding=sliding), f_n


def contact_forces(
    cp: ContactParams, terrain: Terrain, state: ContactState, pos: jax.Array, vel: jax.Array
) -> tuple[jax.Array, ContactState, jax.Array]:
    """Explicit evaluation of the laws at the given velocities (P, 2) (no implicit solve).

    Returns world forces (P, 2) [N], the next contact state and normal forces (P,).
    """
    rows = contact_rows(cp, terrain, state, pos, vel)
    y_n = (vel * rows.normal).sum(-1)
    y_t = (vel * rows.tangent).sum(-1)
    return contact_finalize(cp, rows, state, pos, y_n, y_t)
