"""Planar multibody geometry read from an MJCF file.

The MJCF file is the one source of geometry and inertia.  MJX integrates the multibody
dynamics; this module only reads the model's kinematic tree once (NumPy, static) and gives
cheap, differentiable planar forward kinematics for the quantities the controller and the
contact model need at every step: contact-point positions/velocities, the centre of mass
and joint angles in the Geyer-Herr convention.  :meth:`Body.point_jacobian` gives the
Jacobian of points fixed in bodies analytically (the FBL step uses it for velocities and
J^T F); :meth:`Body.sites_and_velocities` and :meth:`Body.site_forces_to_qfrc` get the same
from ``jax.jvp`` / ``jax.vjp`` of the position map.

Planar convention: the sagittal plane is MuJoCo's x-z plane, every hinge turns about +-y.
A rotation by angle a about +y maps a local vector (x, z) to (x cos a + z sin a,
-x sin a + z cos a).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxgait.core.resources import model_path


@dataclass(frozen=True, eq=False)
class Body:
    """Static description of a planar MJCF body (not a pytree: closed over by jit).

    Attributes:
      mj_model: the compiled MuJoCo model.
      parent: (nbody,) parent body index.
      pos: (nbody, 2) body origin in the parent frame (x, z) [m].
      hinge_q: (nbody,) qpos address of the body's hinge, or -1.
      hinge_sign: (nbody,) +1 if the hinge axis is +y, -1 if -y.
      slide_q: (nbody, 2) qpos addresses of x / z slides, or -1.
      ipos: (nbody, 2) centre of mass in the body frame [m]; mass: (nbody,) [kg].
      site_body, site_pos: site owner body and local position (x, z).
    """

    mj_model: mujoco.MjModel
    parent: np.ndarray
    pos: np.ndarray
    hinge_q: np.ndarray
    hinge_sign: np.ndarray
    slide_q: np.ndarray
    ipos: np.ndarray
    mass: np.ndarray
    site_body: np.ndarray
    site_pos: np.ndarray

    @property
    def mjx_model(self):
        """The MJX model, one per float mode (a float64 copy is kept apart for x64 runs)."""
        from mujoco import mjx

        cache = self.__dict__.setdefault("_mjx_models", {})
        key = bool(jax.config.jax_enable_x64)
        if key not in cache:
            with jax.ensure_compile_time_eval():  # concrete even if first used while tracing
                # on this process's first device (MJX's default is jax.devices()[0], another
                # process's under jax.distributed)
                cache[key] = mjx.put_model(self.mj_model, device=jax.local_devices()[0])
        return cache[key]

    @property
    def total_mass(self) -> float:
        return float(self.mass.sum())

    @property
    def dt(self) -> float:
        return float(self.mj_model.opt.timestep)

    def site_id(self, name: str) -> int:
        i = mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_SITE, name)
        if i < 0:
            raise KeyError(f"site {name!r} not in MJCF model {self.mj_model.names[:40]!r}")
        return i

    def qpos_adr(self, joint: str) -> int:
        i = mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_JOINT, joint)
        if i < 0:
            raise KeyError(f"joint {joint!r} not in MJCF model")
        return int(self.mj_model.jnt_qposadr[i])

    # ---------------------------------------------------------------- kinematics
    def frames(self, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
        """World origin (nbody, 2) and pitch angle (nbody,) of every body."""
        nb = len(self.parent)
        origins = [jnp.zeros(2, qpos.dtype)]
        angles = [jnp.zeros((), qpos.dtype)]
        for b in range(1, nb):
            p = int(self.parent[b])
            ap = angles[p]
            lx, lz = self.pos[b]
            ox = origins[p][0] + lx * jnp.cos(ap) + lz * jnp.sin(ap)
            oz = origins[p][1] - lx * jnp.sin(ap) + lz * jnp.cos(ap)
            if self.slide_q[b, 0] >= 0:
                ox = ox + qpos[self.slide_q[b, 0]]
            if self.slide_q[b, 1] >= 0:
                oz = oz + qpos[self.slide_q[b, 1]]
            a = ap
            if self.hinge_q[b] >= 0:
                a = a + self.hinge_sign[b] * qpos[self.hinge_q[b]]
            origins.append(jnp.stack([ox, oz]))
            angles.append(a)
        return jnp.stack(origins), jnp.stack(angles)

    @staticmethod
    def _local_to_world(origin, angle, local):
        c, s = jnp.cos(angle), jnp.sin(angle)
        return origin + jnp.stack(
            [local[..., 0] * c + local[..., 1] * s, -local[..., 0] * s + local[..., 1] * c], -1
        )

    def sites(self, qpos: jax.Array, ids) -> jax.Array:
        """World (x, z) of the sites ``ids`` -> (len(ids), 2) [m]."""
        o, a = self.frames(qpos)
        ids = np.asarray(ids)
        b = self.site_body[ids]
        return self._local_to_world(o[b], a[b], jnp.asarray(self.site_pos[ids], qpos.dtype))

    def com(self, qpos: jax.Array) -> jax.Array:
        """Whole-body centre of mass (x, z) [m]."""
        o, a = self.frames(qpos)
        w = self._local_to_world(o[1:], a[1:], jnp.asarray(self.ipos[1:], qpos.dtype))
        m = jnp.asarray(self.mass[1:], qpos.dtype)
        return (m[:, None] * w).sum(0) / m.sum()

    def _jacobian_masks(self, point_bodies: tuple[int, ...]):
        """Static masks for :meth:`point_jacobian` (cached per tuple of owner bodies)."""
        cache = self.__dict__.setdefault("_jac_masks", {})
        if point_bodies not in cache:
            nv = self.mj_model.nv
            hinge = np.zeros((len(point_bodies), nv))
            slide = np.zeros((len(point_bodies), 2, nv))
            dof_body = np.zeros(nv, np.int32)
            for i, b in enumerate(point_bodies):
                while b > 0:  # the chain from the point's body to the world
                    if self.hinge_q[b] >= 0:
                        hinge[i, self.hinge_q[b]] = self.hinge_sign[b]
                        dof_body[self.hinge_q[b]] = b
                    for k in range(2):
                        if self.slide_q[b, k] >= 0:
                            slide[i, k, self.slide_q[b, k]] = 1.0
                    b = int(self.parent[b])
            cache[point_bodies] = (hinge, slide, dof_body)
        return cache[point_bodies]

    def point_jacobian(self, origins, points, point_bodies) -> jax.Array:
        """Jacobian d(points)/d(qpos) (P, 2, nv) of world points fixed in bodies, analytically.

        ``origins`` are the body origins of :meth:`frames`, ``points`` (P, 2) world positions
        and ``point_bodies`` a static tuple of the bodies that carry them.  A hinge of sign s
        at the origin o of an ancestor body moves a point p by s (p_z - o_z, -(p_x - o_x))
        per radian (rotation about +y); a slide moves it along its axis.  Joints sit at
        their body origins (checked when the MJCF is loaded).
        """
        hinge, slide, dof_body = self._jacobian_masks(tuple(int(b) for b in point_bodies))
        dt = points.dtype
        r = points[:, None, :] - origins[dof_body][None, :, :]  # (P, nv, 2)
        h = jnp.asarray(hinge, dt)
        jx = h * r[..., 1]
        jz = -h * r[..., 0]
        return jnp.stack([jx, jz], 1) + jnp.asarray(slide, dt)

    # ---------------------------------------------------------------- dynamics
    def _dynamics_constants(self):
        """Static arrays of :meth:`mass_and_bias` (cached): the angular-velocity Jacobian
        (nbody, nv), the ancestor mask (nbody, nbody), the rotational part of M (nv, nv) and
        the gravity vector (x, z)."""
        cache = self.__dict__.setdefault("_dyn_consts", None)
        if cache is None:
            m = self.mj_model
            nb, nv = len(self.parent), m.nv
            passive = {
                "joint damping": m.dof_damping,
                "joint armature": m.dof_armature,
                "joint stiffness": m.jnt_stiffness,
                "joint friction loss": m.dof_frictionloss,
            }
            for what, v in passive.items():
                if np.any(np.asarray(v) != 0):
                    raise ValueError(
                        f"planar dynamics: the MJCF has {what}; use SimConfig(dynamics='mjx')"
                    )
            if not np.allclose(m.body_iquat[1:], [1, 0, 0, 0]):
                raise ValueError(
                    "planar dynamics: a body's inertia frame is rotated; "
                    "use SimConfig(dynamics='mjx')"
                )
            jw = np.zeros((nb, nv))  # d(pitch)/d(qvel): the hinges up to the world
            anc = np.zeros((nb, nb))  # anc[b, k] = 1 if body k is b or one of its ancestors
            for b in range(1, nb):
                k = b
                while k > 0:
                    anc[b, k] = 1.0
                    if self.hinge_q[k] >= 0:
                        jw[b, self.hinge_q[k]] = self.hinge_sign[k]
                    k = int(self.parent[k])
            inertia = np.asarray(m.body_inertia[:, 1])  # about the hinge axis (y)
            m_rot = np.einsum("b,bn,bm->nm", inertia[1:], jw[1:], jw[1:])
            gravity = np.asarray(m.opt.gravity)[[0, 2]]
            cache = self.__dict__["_dyn_consts"] = (jw, anc, m_rot, gravity)
        return cache

    def mass_and_bias(self, qpos: jax.Array, qvel: jax.Array):
        """Joint-space mass matrix M (nv, nv) and bias force (nv,) of the planar tree.

        The rigid-body equations of motion M(q) q_dd + b(q, q_d) = tau of the MJCF's bodies
        (masses, centres of mass and y-axis inertias as MuJoCo compiles them), written for
        the planar tree: with J_b the Jacobian of body b's centre of mass and j_b the
        (constant) row of its pitch rate,

            M = sum_b m_b J_b^T J_b + I_b j_b^T j_b,
            b = sum_b m_b J_b^T (a_b - g),

        a_b the velocity-product acceleration of the centre of mass, J_b_dot q_d: each body k
        on the chain from the root to b turns its segment r_k (from its parent's origin to its
        own origin, and from b's origin to the centre of mass) at its pitch rate w, so
        a_b = -sum_k w_parent(k)^2 r_k - w_b^2 (c_b - o_b).  A planar body has no gyroscopic
        torque and MuJoCo's bias is C(q, q_d) q_d + gravity (no passive forces in these
        models: no joint damping, springs, armature or friction loss, checked here).  Equal
        to MJX's composite-rigid-body and recursive Newton-Euler passes to rounding
        (``tests/test_planar_dynamics.py``), in far fewer operations.
        """
        jw_np, anc_np, m_rot, gravity = self._dynamics_constants()
        dt = qpos.dtype
        nb = len(self.parent)
        o, a = self.frames(qpos)
        com = self._local_to_world(o[1:], a[1:], jnp.asarray(self.ipos[1:], dt))  # (nb-1, 2)
        jac = self.point_jacobian(o, com, tuple(range(1, nb)))  # (nb-1, 2, nv)
        mass = jnp.asarray(self.mass[1:], dt)
        jw = jnp.asarray(jw_np, dt)
        omega = jnp.sum(jw * qvel[None, :], axis=1)  # (nb,) pitch rates, world's 0
        par = np.asarray(self.parent)
        seg = (o[1:] - o[par[1:]]) * jnp.square(omega[par[1:]])[:, None]  # (nb-1, 2)
        anc = jnp.asarray(anc_np[1:, 1:], dt)
        acc = -jnp.sum(anc[:, :, None] * seg[None, :, :], axis=1)
        acc = acc - jnp.square(omega[1:])[:, None] * (com - o[1:])
        mj = mass[:, None, None] * jac
        M = jnp.sum(mj[:, :, :, None] * jac[:, :, None, :], axis=(0, 1)) + jnp.asarray(m_rot, dt)
        bias = jnp.sum(mj * (acc - jnp.asarray(gravity, dt))[:, :, None], axis=(0, 1))
        return M, bias

    def sites_and_velocities(self, qpos, qvel, ids):
        """Site positions and velocities (len(ids), 2) via forward-mode AD."""
        return jax.jvp(lambda q: self.sites(q, ids), (qpos,), (qvel,))

    def site_forces_to_qfrc(self, qpos, forces, ids) -> jax.Array:
        """Generalised force J^T F of world forces (len(ids), 2) acting at the sites."""
        _, vjp = jax.vjp(lambda q: self.sites(q, ids), qpos)
        return vjp(forces)[0]


def _planar_check(m: mujoco.MjModel, path) -> None:
    for j in range(m.njnt):
        name = m.joint(j).name
        if np.any(np.abs(m.jnt_pos[j]) > 0):
            raise ValueError(f"{path}: joint {name!r} has an offset pos; planar bodies need 0")
        ax = m.jnt_axis[j]
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            if not (abs(abs(ax[1]) - 1) < 1e-9 and abs(ax[0]) < 1e-9 and abs(ax[2]) < 1e-9):
                raise ValueError(f"{path}: hinge {name!r} axis {ax} is not +-y (planar model)")
        elif m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            if abs(ax[1]) > 1e-9 or not (abs(abs(ax[0]) - 1) < 1e-9 or abs(abs(ax[2]) - 1) < 1e-9):
                raise ValueError(f"{path}: slide {name!r} axis {ax} is not x or z")
        else:
            raise ValueError(f"{path}: joint {name!r} type {m.jnt_type[j]} not planar")
    for b in range(1, m.nbody):
        if not np.allclose(m.body_quat[b], [1, 0, 0, 0]) or abs(m.body_pos[b][1]) > 1e-9:
            raise ValueError(f"{path}: body {m.body(b).name!r} is rotated or off the x-z plane")
        if not np.allclose(m.body_iquat[b], [1, 0, 0, 0]):
            # diagonal inertia in the body frame is assumed by the planar CoM only through ipos
            pass


def load_body(name: str = "fbl_planar", timestep: float | None = None) -> Body:
    """Compile the MJCF ``name`` from the models folder into a :class:`Body`.

    ``timestep`` [s] overrides the MJCF's ``<option timestep>`` (e.g. for convergence checks).
    """
    path = model_path(name)
    m = mujoco.MjModel.from_xml_path(str(path))
    if timestep is not None:
        if not timestep > 0:
            raise ValueError(f"timestep must be > 0, got {timestep}")
        m.opt.timestep = float(timestep)
    _planar_check(m, path)
    nb = m.nbody
    hinge_q = -np.ones(nb, int)
    hinge_sign = np.ones(nb)
    slide_q = -np.ones((nb, 2), int)
    for j in range(m.njnt):
        b = m.jnt_bodyid[j]
        adr = m.jnt_qposadr[j]
        ax = m.jnt_axis[j]
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            if hinge_q[b] >= 0:
                raise ValueError(f"{path}: body {m.body(b).name!r} has two hinges")
            hinge_q[b] = adr
            hinge_sign[b] = np.sign(ax[1])
        else:
            k = 0 if abs(ax[0]) > 0.5 else 1
            if np.sign(ax[k]) < 0:
                raise ValueError(f"{path}: slide axes must point along +x / +z")
            slide_q[b, k] = adr
    return Body(
        mj_model=m,
        parent=np.asarray(m.body_parentid).copy(),
        pos=np.asarray(m.body_pos[:, [0, 2]]).copy(),
        hinge_q=hinge_q,
        hinge_sign=hinge_sign,
        slide_q=slide_q,
        ipos=np.asarray(m.body_ipos[:, [0, 2]]).copy(),
        mass=np.asarray(m.body_mass).copy(),
        site_body=np.asarray(m.site_bodyid).copy(),
        site_pos=np.asarray(m.site_pos[:, [0, 2]]).copy(),
    )
