"""Walking environments (thesis 2.2.4) as pure functions of a PRNG key and a frozen config.

Every environment is one pytree type, :class:`Env` = (:class:`~jaxgait.world.terrain.Terrain`,
:class:`Pushes`), with a fixed knot count K (``n_knots``) and push capacity P (``n_pushes``)
shared by all kinds, so environments of different kinds stack into one batch and the step
function never branches on the kind.  Environments without pushes carry P zero-magnitude
pushes; environments on level ground carry flat terrain padded to K knots.

Registry (:data:`ENVIRONMENTS`, thesis numbering in brackets):

=====================  ==================================================================
``flat``               level ground [1]
``slope_up``           constant upward grade (default +5 %)
``slope_down``         constant downward grade (default -5 %)
``push``               one push of fixed amplitude at a uniformly random time [2]
``random_push``        a series of random pushes, growing amplitude [3] (2.2.4.1, Fig. 2.7)
``wavy``               trapezoids of increasing angle, random lengths [4] (2.2.4.2, Fig. 2.8)
``increasing_slope``   grade rising from 0 to 30 % over 160 m [5] (7.3.1, Fig. 7.5)
``weight_support``     level ground, a share of the body weight carried by a harness
=====================  ==================================================================

The same key always gives the same environment, so every evaluation can be replayed.

Push convention: a push is a constant force of ``magnitude`` [N] during
[t0, t0 + duration) [s] applied to the trunk at ``height`` [m] from the hip along the trunk
axis.  ``angle`` [rad] is the angle of the force to the ground (world horizontal): 0 pushes
horizontally forward (+x, the walking direction), positive angles add an upward component
(+pi/2 = straight up), |angle| > pi/2 pushes backwards.  So fx = F cos(angle),
fz = F sin(angle).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.world.terrain import (
    DEFAULT_N_KNOTS,
    IncreasingSlopeConfig,
    Terrain,
    WavyConfig,
    flat,
    increasing_slope,
    slope,
    wavy,
)

G = 9.81
"""Gravitational acceleration [m/s^2] (the MJCF's)."""

SUPPORT_DURATION_S = 1.0e6
"""How long the support of ``weight_support`` acts [s]: longer than any rollout."""

#: Steps of a fading support (``WeightSupportEnv.fade_s``), one push slot each.
FADE_STEPS = 16

DEFAULT_N_PUSHES = 128
"""Default push capacity P: 128 random pushes last ~160 s on average (1.25 s per push+pause),
more than a 120 m walk at 1.3 m/s (~92 s, thesis 3.2)."""


def _check(ok: bool, name: str, value, rule: str) -> None:
    if not ok:
        raise ValueError(f"invalid {name}={value!r}: must be {rule}")


# ---------------------------------------------------------------------------------------------
# Pushes
# ---------------------------------------------------------------------------------------------


@struct.dataclass
class Pushes:
    """P pushes on the trunk (see the module docstring for the convention).

    Attributes:
      t0: (P,) start time [s].
      duration: (P,) duration [s]; the push acts on [t0, t0 + duration).
      magnitude: (P,) force magnitude [N] (0 = unused slot).
      angle: (P,) angle of the force to the ground [rad]; 0 = horizontal forward, > 0 upward.
      height: (P,) point of application along the trunk [m from the hip].
    """

    t0: jax.Array
    duration: jax.Array
    magnitude: jax.Array
    angle: jax.Array
    height: jax.Array

    @classmethod
    def empty(cls, n_pushes: int, dtype=jnp.float32) -> Pushes:
        """P unused slots (zero magnitude and duration): no force at any time."""
        z = jnp.zeros((n_pushes,), dtype)
        return cls(t0=z, duration=z, magnitude=z, angle=z, height=z)


def push_forces(pushes: Pushes, t):
    """Per-push force at time ``t`` [s].

    Returns:
      fx, fz: (P,) force components [N] (zero for pushes not active at t).
      height: (P,) application heights [m from the hip] (as stored).
    """
    active = (t >= pushes.t0) & (t < pushes.t0 + pushes.duration)
    f = jnp.where(active, pushes.magnitude, 0.0)
    return f * jnp.cos(pushes.angle), f * jnp.sin(pushes.angle), pushes.height


def push_force(pushes: Pushes, t):
    """Total push force at time ``t`` [s] (pure, vmap-able over pushes and t).

    Returns:
      fx, fz: scalar force components [N], the sum over the active pushes.
      height: application height [m from the hip]: the magnitude-weighted mean height of the
        active pushes (0 if none).  Exact whenever at most one push is active, which holds for
        the ``push`` and ``random_push`` environments by construction (a pause separates
        successive pushes); for user-made overlapping pushes at different heights use
        :func:`push_forces` and apply each force at its own point.
    """
    fx, fz, h = push_forces(pushes, t)
    active = (t >= pushes.t0) & (t < pushes.t0 + pushes.duration)
    w = jnp.where(active, jnp.abs(pushes.magnitude), 0.0)
    wsum = jnp.sum(w)
    height = jnp.where(wsum > 0, jnp.sum(w * h) / jnp.maximum(wsum, 1e-12), 0.0)
    return jnp.sum(fx), jnp.sum(fz), height


# Gamma and chi-square variates with integer shape are drawn exactly as sums (Erlang:
# exponentials; chi-square: squared normals).  With one random draw per environment this
# compiles several times faster than ``jax.random.gamma``'s rejection loop, which matters
# because environments are drawn inside the jitted optimisation step.
_MAX_DOF = 64


def _check_count(name: str, v, lo: int = 1) -> int:
    ok = isinstance(v, int) and not isinstance(v, bool) and lo <= v <= _MAX_DOF
    _check(ok, name, v, f"an integer in [{lo}, {_MAX_DOF}]")
    return v


def _chi2(z: jax.Array) -> jax.Array:
    """Chi-square(d) from (..., d) standard normals: sum of squares (= 2 Gamma(d / 2, 1))."""
    return jnp.sum(z * z, -1)


def _erlang(u: jax.Array) -> jax.Array:
    """Gamma(k, 1) from (..., k) uniforms on [0, 1): sum of k unit exponentials."""
    return -jnp.sum(jnp.log1p(-u), -1)  # 1 - u in (0, 1]


def _f_from_normals(z: jax.Array, df1: int, df2: int) -> jax.Array:
    """F(df1, df2) = (chi2_df1 / df1) / (chi2_df2 / df2) from (..., df1 + df2) normals."""
    return (_chi2(z[..., :df1]) / df1) / jnp.maximum(_chi2(z[..., df1:]) / df2, 1e-12)


def sample_gamma(key: jax.Array, k: int, shape, dtype=jnp.float32) -> jax.Array:
    """Gamma(k, scale 1) samples for an integer shape k in [1, 64] (exact, Erlang)."""
    k = _check_count("k", k)
    return _erlang(jax.random.uniform(key, (*shape, k), dtype))


def sample_f(key: jax.Array, df1: int, df2: int, shape, dtype=jnp.float32) -> jax.Array:
    """F(df1, df2) samples (integer degrees of freedom in [1, 64]); mean df2 / (df2 - 2).

    Built from chi-square variates, chi2(d) = sum of d squared normals = 2 Gamma(d / 2, 1).
    """
    df1, df2 = _check_count("df1", df1), _check_count("df2", df2)
    return _f_from_normals(jax.random.normal(key, (*shape, df1 + df2), dtype), df1, df2)


# ---------------------------------------------------------------------------------------------
# Environment pytree and configs
# ---------------------------------------------------------------------------------------------


@struct.dataclass
class Env:
    """One environment: ground profile (K knots) and pushes (P slots)."""

    terrain: Terrain
    pushes: Pushes

    def push_force(self, t):
        """:func:`push_force` of this environment's pushes at time ``t`` [s]."""
        return push_force(self.pushes, t)


@dataclass(frozen=True)
class EnvConfig:
    """Base config (also the ``flat`` environment): level ground, no pushes.

    Attributes:
      n_knots: K, terrain knot count (shared by all kinds to batch them together).
      n_pushes: P, push capacity (shared likewise).
    """

    n_knots: int = DEFAULT_N_KNOTS
    n_pushes: int = DEFAULT_N_PUSHES

    def __post_init__(self):
        _check(isinstance(self.n_knots, int) and self.n_knots >= 3, "n_knots", self.n_knots, ">= 3")
        _check(
            isinstance(self.n_pushes, int) and self.n_pushes >= 1, "n_pushes", self.n_pushes, ">= 1"
        )

    def make_terrain(self, key: jax.Array) -> Terrain:
        """Ground of this environment (K knots)."""
        del key
        return flat(n_knots=self.n_knots)

    def make_pushes(self, key: jax.Array) -> Pushes:
        """Pushes of this environment (P slots)."""
        del key
        return Pushes.empty(self.n_pushes)

    def build(self, key: jax.Array) -> Env:
        """The environment drawn from ``key`` (pure; jit-able with the config static)."""
        k_terrain, k_pushes = jax.random.split(key)
        return Env(terrain=self.make_terrain(k_terrain), pushes=self.make_pushes(k_pushes))


@dataclass(frozen=True)
class FlatEnv(EnvConfig):
    """Environment 1: flat ground (thesis 2.2.4)."""


@dataclass(frozen=True)
class SlopeEnv(EnvConfig):
    """Level ground up to ``start`` [m], then a constant ``grade`` (rise/run, < 0 downhill).

    Default |grade| = 5 %: the slope change the best thesis gaits withstood (thesis 3.2.3).
    """

    grade: float = 0.05
    start: float = 2.0

    def make_terrain(self, key):
        del key
        return slope(self.grade, start=self.start, n_knots=self.n_knots)


@dataclass(frozen=True)
class PushEnv(EnvConfig):
    """Environment 2: one push of fixed amplitude at a uniformly random time (thesis 2.2.4).

    The thesis gives no numbers for this environment; the defaults take the 80 N pushes of
    0.25 s the optimised gaits withstood (thesis 3.2.2) at mid-trunk, horizontally forward,
    at a time uniform in [t_min, t_max] once the gait has settled (window chosen here).

    Attributes:
      magnitude: [N]; duration: [s]; angle: [rad] (0 = horizontal forward);
      height: [m from the hip]; t_min, t_max: start-time window [s].
    """

    magnitude: float = 80.0
    duration: float = 0.25
    angle: float = 0.0
    height: float = 0.4
    t_min: float = 3.0
    t_max: float = 8.0

    def __post_init__(self):
        super().__post_init__()
        _check(self.t_max >= self.t_min, "t_max", self.t_max, f">= t_min = {self.t_min}")
        _check(self.duration >= 0, "duration", self.duration, ">= 0")

    def make_pushes(self, key):
        t0 = jax.random.uniform(key, (), jnp.float32, self.t_min, self.t_max)
        p = Pushes.empty(self.n_pushes)
        return p.replace(
            t0=p.t0.at[0].set(t0),
            duration=p.duration.at[0].set(self.duration),
            magnitude=p.magnitude.at[0].set(self.magnitude),
            angle=p.angle.at[0].set(self.angle),
            height=p.height.at[0].set(self.height),
        )


@dataclass(frozen=True)
class WeightSupportEnv(EnvConfig):
    """Level ground with body-weight support: a harness pulls the trunk straight up.

    A constant vertical force ``fraction * mass * g`` [N] on the trunk at ``height`` [m from
    the hip along the trunk axis], from t = 0 to the end of the rollout, in push slot 0 (the
    push convention above, angle +pi/2).  This is the body-weight-supported treadmill of gait
    rehabilitation, here a training aid: a search can start under support, where flight is
    cheap, and lower the support stage by stage (``experiments/running``).  Not a thesis
    environment.

    With ``fade_s`` > 0 the support fades out within the rollout: it falls linearly from the
    full force at t = 0 to none at ``fade_s``, in ``min(FADE_STEPS, n_pushes)`` equal steps
    (one push slot each, the force of step k the line's value at the step's middle), and the
    body is on its own after ``fade_s``: a search on it rewards gaits that start under
    support and keep going without.

    With ``angle`` other than pi/2 the harness pulls along that direction (the push
    convention: 0 pulls straight forwards): a tow of ``fraction * mass * g`` [N], a training
    aid for gaits faster than the body runs alone (``experiments/running``).

    Attributes:
      fraction: share of the body weight carried (the force in body weights), in [0, 1).
      mass: body mass [kg] the share is taken of (the planar body's 80 kg).
      height: point of application [m from the hip]; 0.3 m is near the trunk's centre of mass.
      fade_s: time [s] over which the support fades to none; 0 (default): constant support.
      angle: direction of the pull [rad], pi/2 (default) straight up, 0 straight forwards.
    """

    fraction: float = 0.3
    mass: float = 80.0
    height: float = 0.3
    fade_s: float = 0.0
    angle: float = math.pi / 2

    def __post_init__(self):
        super().__post_init__()
        _check(0.0 <= self.fraction < 1.0, "fraction", self.fraction, "in [0, 1)")
        _check(self.mass > 0, "mass", self.mass, "> 0 [kg]")
        ok = isinstance(self.fade_s, (int, float)) and 0.0 <= self.fade_s < math.inf
        _check(ok, "fade_s", self.fade_s, ">= 0 and finite [s] (0: constant support)")
        ok = isinstance(self.angle, (int, float)) and -math.pi <= self.angle <= math.pi
        _check(ok, "angle", self.angle, "in [-pi, pi] [rad] (pi/2: straight up)")

    @property
    def force(self) -> float:
        """The support force [N]."""
        return self.fraction * self.mass * G

    def make_pushes(self, key):
        del key
        p = Pushes.empty(self.n_pushes)
        if self.fade_s > 0.0:
            n = min(FADE_STEPS, self.n_pushes)
            step = self.fade_s / n
            k = jnp.arange(n, dtype=jnp.float32)
            return p.replace(
                t0=p.t0.at[:n].set(k * step),
                duration=p.duration.at[:n].set(step),
                magnitude=p.magnitude.at[:n].set(self.force * (1.0 - (k + 0.5) / n)),
                angle=p.angle.at[:n].set(self.angle),
                height=p.height.at[:n].set(self.height),
            )
        return p.replace(
            t0=p.t0.at[0].set(0.0),
            duration=p.duration.at[0].set(SUPPORT_DURATION_S),
            magnitude=p.magnitude.at[0].set(self.force),
            angle=p.angle.at[0].set(self.angle),
            height=p.height.at[0].set(self.height),
        )


@dataclass(frozen=True)
class RandomPushEnv(EnvConfig):
    """Environment 3: random pushes on flat ground (thesis 2.2.4.1, Fig. 2.7).

    Push i (0-based, all P slots used) starts after a pause following push i-1 (after
    ``t_start`` for i = 0).  Thesis (Fig. 2.7): pauses F-distributed "so that the push arises
    approximately each second", durations gamma-distributed, angle ~ N(0, sd pi/2), height
    uniform over the trunk, amplitude ~ N(mean_i, sd_i) with mean and SD increasing linearly
    push after push towards a maximum.  Numbers:

    * pause = s * F(interval_df1, interval_df2) with s = interval_mean (df2 - 2) / df2, so
      E[pause] = interval_mean = 1 s (thesis); the degrees of freedom (20, 20) are chosen here
      (SD of the pause ~0.49 s).
    * duration ~ Gamma(shape=duration_shape, scale=duration_mean / duration_shape): mean
      0.25 s (thesis 3.2.2); shape 4 (SD 0.125 s) is chosen here.
    * The degrees of freedom and the gamma shape are integers (1..64): chi-square and gamma
      variates are then exact sums of squared normals / exponentials (:func:`sample_f`,
      :func:`sample_gamma`), drawn in one batch per environment.
    * angle ~ N(angle_mean = 0, angle_sd = pi/2) (thesis Fig. 2.7).
    * height ~ U(0, trunk_length), trunk_length = 0.8 m (thesis Table 2.2).
    * magnitude ~ N(m_i, s_i), clipped at 0, with r_i = min((i + 1) / n_ramp, 1),
      m_i = r_i * magnitude_mean_max, s_i = r_i * magnitude_sd_max.  The maxima (120 N, 20 N)
      and the 60 pushes to reach them (~75 s) are chosen here: 1.5x the 80 N the optimised
      gaits withstood (thesis 3.2.2), reached before a 120 m walk at 1.3 m/s ends.
    """

    t_start: float = 2.0
    interval_mean: float = 1.0
    interval_df1: int = 20
    interval_df2: int = 20
    duration_mean: float = 0.25
    duration_shape: int = 4
    angle_mean: float = 0.0
    angle_sd: float = math.pi / 2
    trunk_length: float = 0.8
    magnitude_mean_max: float = 120.0
    magnitude_sd_max: float = 20.0
    n_ramp: int = 60

    def __post_init__(self):
        super().__post_init__()
        _check_count("interval_df1", self.interval_df1)
        _check_count("interval_df2", self.interval_df2, lo=3)  # finite mean needs df2 > 2
        _check(self.interval_mean > 0, "interval_mean", self.interval_mean, "> 0")
        _check(self.duration_mean > 0, "duration_mean", self.duration_mean, "> 0")
        _check_count("duration_shape", self.duration_shape)
        _check(self.angle_sd >= 0, "angle_sd", self.angle_sd, ">= 0")
        _check(self.trunk_length > 0, "trunk_length", self.trunk_length, "> 0")
        _check(self.magnitude_sd_max >= 0, "magnitude_sd_max", self.magnitude_sd_max, ">= 0")
        _check(self.n_ramp >= 1, "n_ramp", self.n_ramp, ">= 1")

    @property
    def interval_scale(self) -> float:
        """s such that s * F(df1, df2) has mean ``interval_mean`` [s]."""
        return self.interval_mean * (self.interval_df2 - 2.0) / self.interval_df2

    def ramp(self) -> jax.Array:
        """(P,) r_i = min((i + 1) / n_ramp, 1): fraction of the maximal mean/SD of push i."""
        i = jnp.arange(self.n_pushes, dtype=jnp.float32)
        return jnp.minimum((i + 1.0) / self.n_ramp, 1.0)

    def make_pushes(self, key):
        n, f32 = self.n_pushes, jnp.float32
        d1, d2, k = self.interval_df1, self.interval_df2, self.duration_shape
        k_z, k_u = jax.random.split(key)
        # one draw of normals and one of uniforms per push (columns split below)
        z = jax.random.normal(k_z, (n, 2 + d1 + d2), f32)  # angle, magnitude, F numerator/denom.
        u = jax.random.uniform(k_u, (n, 1 + k), f32)  # height, Erlang terms
        pause = self.interval_scale * _f_from_normals(z[:, 2:], d1, d2)
        duration = self.duration_mean / k * _erlang(u[:, 1:])
        # push i starts after all previous pushes and pauses 0..i
        prev = jnp.concatenate([jnp.zeros(1, f32), jnp.cumsum(duration)[:-1]])
        t0 = self.t_start + jnp.cumsum(pause) + prev
        angle = self.angle_mean + self.angle_sd * z[:, 0]
        height = self.trunk_length * u[:, 0]
        mag = self.ramp() * (self.magnitude_mean_max + self.magnitude_sd_max * z[:, 1])
        return Pushes(
            t0=t0, duration=duration, magnitude=jnp.maximum(mag, 0.0), angle=angle, height=height
        )


@dataclass(frozen=True)
class WavyEnv(EnvConfig, WavyConfig):
    """Environment 4: wavy ground, no pushes; fields of
    :class:`~jaxgait.world.terrain.WavyConfig`."""

    def __post_init__(self):
        EnvConfig.__post_init__(self)
        WavyConfig.__post_init__(self)

    def make_terrain(self, key):
        return wavy(key, self)


@dataclass(frozen=True)
class IncreasingSlopeEnv(EnvConfig, IncreasingSlopeConfig):
    """Environment 5: increasing slope, no pushes; fields of
    :class:`~jaxgait.world.terrain.IncreasingSlopeConfig` (0 -> 30 % over 160 m, thesis 7.3.1)."""

    def __post_init__(self):
        EnvConfig.__post_init__(self)
        IncreasingSlopeConfig.__post_init__(self)

    def make_terrain(self, key):
        del key
        return increasing_slope(self)


# ---------------------------------------------------------------------------------------------
# Registry and constructors
# ---------------------------------------------------------------------------------------------

ENVIRONMENTS: dict[str, EnvConfig] = {
    "flat": FlatEnv(),
    "slope_up": SlopeEnv(grade=0.05),
    "slope_down": SlopeEnv(grade=-0.05),
    "push": PushEnv(),
    "random_push": RandomPushEnv(),
    "wavy": WavyEnv(),
    "increasing_slope": IncreasingSlopeEnv(),
    "weight_support": WeightSupportEnv(),
}
"""Default config of every named environment (thesis 2.2.4)."""


def get_env_config(name: str, **overrides) -> EnvConfig:
    """Config of environment ``name`` with fields replaced by ``overrides``.

    Raises:
      ValueError: unknown environment name or field (the message lists the valid ones), or an
        invalid value.
    """
    if name not in ENVIRONMENTS:
        raise ValueError(f"unknown environment {name!r}; valid names: {', '.join(ENVIRONMENTS)}")
    base = ENVIRONMENTS[name]
    fields = [f.name for f in dataclasses.fields(base)]
    unknown = sorted(set(overrides) - set(fields))
    if unknown:
        raise ValueError(
            f"unknown field(s) {', '.join(unknown)} for environment {name!r} "
            f"({type(base).__name__}); valid fields: {', '.join(fields)}"
        )
    return dataclasses.replace(base, **overrides)


def _as_config(name_or_cfg: str | EnvConfig) -> EnvConfig:
    if isinstance(name_or_cfg, str):
        return get_env_config(name_or_cfg)
    if not isinstance(name_or_cfg, EnvConfig):
        raise TypeError(
            f"expected an environment name or EnvConfig, got {type(name_or_cfg).__name__}"
        )
    return name_or_cfg


@functools.partial(jax.jit, static_argnums=0)
def _build(cfg: EnvConfig, key: jax.Array) -> Env:
    return cfg.build(key)


@functools.partial(jax.jit, static_argnums=0)
def _build_batch(cfg: EnvConfig, keys: jax.Array) -> Env:
    return jax.vmap(cfg.build)(keys)


def make_env(name_or_cfg: str | EnvConfig, key: jax.Array) -> Env:
    """The environment ``name_or_cfg`` drawn from ``key`` (same key -> identical env)."""
    return _build(_as_config(name_or_cfg), key)


def make_env_batch(name_or_cfg: str | EnvConfig, keys: jax.Array) -> Env:
    """A batch of environments, one per key (leading axis of every leaf = len(keys))."""
    return _build_batch(_as_config(name_or_cfg), keys)


def stack_envs(envs) -> Env:
    """Stack environments (possibly of different kinds, same K and P) into one batch."""
    envs = list(envs)
    shapes = {(e.terrain.xs.shape, e.pushes.t0.shape) for e in envs}
    if len(shapes) != 1:
        raise ValueError(f"environments differ in (knots, pushes) shapes: {sorted(shapes)}")
    return jax.tree.map(lambda *x: jnp.stack(x), *envs)
