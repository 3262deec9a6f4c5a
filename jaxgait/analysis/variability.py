"""Periodic variability of a signal over gait cycles (thesis 6.4, eq. 6.10-6.15, Fig. 6.4).

From a sampled signal and the sample indices of its cycle starts (the leg's swing -> stance
transitions):

1. cut the signal into cycles S_i, i = 1..M (thesis 6.4.1);
2. normalise each cycle by its own mean mu_i and SD sigma_i (eq. 6.10); a cycle whose SD is
   below ``eps`` (a silent signal) normalises to zeros;
3. make each normalised cycle continuous by a cubic spline over its sample times and resample
   it at N equally spaced phases [0, 1) (the nominal-function step);
4. the reference S_ref is the mean of the resampled cycles; the stability factor is
   s = sum_ij (S_ref[j] - S_i[j])^2 / (M N) (eq. 6.11), which is about sigma^2 for a periodic
   signal with white noise of SD sigma relative to the signal's SD (eq. 6.13; s < 0.1 is
   "periodic enough");
5. v_mu = std(mu_i) and v_sigma = std(sigma_i) (eq. 6.14-6.15), in the signal's units.

Pure numpy/scipy on the host (a post-processing of recorded rollouts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Points per resampled cycle (thesis 6.4.3 builds its splines on 100 knots).
N_POINTS = 100
#: Stability-factor threshold below which a signal is periodic enough (thesis 6.4.2).
S_PERIODIC = 0.1


@dataclass(frozen=True)
class Variability:
    """Variability of one signal.

    Attributes:
      s: stability factor (eq. 6.11) [-].
      v_mu, v_sigma: SD over cycles of the cycle means and SDs (eq. 6.14-6.15) [signal units].
      mu, sigma: (M,) per-cycle means and SDs [signal units].
      pattern: (N,) mean normalised cycle S_ref (the nominal pattern g^n) [-].
      durations: (M,) cycle durations [s].
      mean_active: mean of the signal over the samples where ``active`` (the IN_SD gate) was
        on, or over all samples when no gate is given [signal units].
    """

    s: float
    v_mu: float
    v_sigma: float
    mu: np.ndarray
    sigma: np.ndarray
    pattern: np.ndarray
    durations: np.ndarray
    mean_active: float

    @property
    def n_cycles(self) -> int:
        return int(self.mu.size)

    @property
    def mean(self) -> float:
        """Mean over cycles of the cycle means [signal units]."""
        return float(np.mean(self.mu))

    @property
    def sd(self) -> float:
        """Mean over cycles of the cycle SDs [signal units]."""
        return float(np.mean(self.sigma))


def cycle_starts(stance: np.ndarray) -> np.ndarray:
    """Sample indices where ``stance`` (T,) turns from False to True (touchdowns)."""
    st = np.asarray(stance, bool)
    return np.flatnonzero(st[1:] & ~st[:-1]) + 1


def resample_cycle(t: np.ndarray, y: np.ndarray, n: int = N_POINTS) -> np.ndarray:
    """(n,) the samples y at times t (one cycle, t[-1] = the next cycle's start) through a
    cubic spline, at n equally spaced phases of [t[0], t[-1])."""
    from scipy.interpolate import CubicSpline

    u = t[0] + (t[-1] - t[0]) * np.arange(n) / n
    if y.size < 4:
        return np.interp(u, t, y)
    return CubicSpline(t, y)(u)


def variability(
    t: np.ndarray,
    signal: np.ndarray,
    starts: np.ndarray,
    n: int = N_POINTS,
    skip: int = 0,
    active: np.ndarray | None = None,
    eps: float = 1e-9,
) -> Variability:
    """The variability factors of ``signal`` (T,) sampled at ``t`` (T,) [s].

    Args:
      starts: sample indices of the cycle starts (:func:`cycle_starts`); a cycle runs from one
        start to the next (its end sample included in the spline, the resampling excludes it).
      n: resampled points per cycle; skip: leading cycles left out (the start transient).
      active: optional (T,) bool IN_SD gate, for :attr:`Variability.mean_active`.
      eps: SD below which a cycle counts as silent.
    Raises ValueError when fewer than 2 cycles remain.
    """
    t, y = np.asarray(t, float), np.asarray(signal, float)
    starts = np.asarray(starts, int)[skip:]
    if starts.size < 3:
        raise ValueError(
            f"need at least 2 whole cycles after skipping {skip}, got {max(starts.size - 1, 0)}"
        )
    cyc, mus, sds, durs = [], [], [], []
    for a, b in zip(starts[:-1], starts[1:], strict=False):
        seg, ts = y[a : b + 1], t[a : b + 1]
        mu, sd = float(np.mean(seg[:-1])), float(np.std(seg[:-1]))
        norm = (seg - mu) / sd if sd > eps else np.zeros_like(seg)
        cyc.append(resample_cycle(ts, norm, n))
        mus.append(mu)
        sds.append(sd)
        durs.append(ts[-1] - ts[0])
    cyc = np.stack(cyc)
    ref = cyc.mean(0)
    s = float(np.mean((ref[None] - cyc) ** 2))
    lo, hi = starts[0], starts[-1]
    if active is None:
        mean_active = float(np.mean(y[lo:hi]))
    else:
        on = np.asarray(active, bool)[lo:hi]
        mean_active = float(np.mean(y[lo:hi][on])) if on.any() else 0.0
    return Variability(
        s=s,
        v_mu=float(np.std(mus)),
        v_sigma=float(np.std(sds)),
        mu=np.asarray(mus),
        sigma=np.asarray(sds),
        pattern=ref,
        durations=np.asarray(durs),
        mean_active=mean_active,
    )


def noisy_sine(noise: float, m: int = 1000, n: int = N_POINTS, seed: int = 0):
    """(t, signal, starts) of m periods of sin(2 pi t), n samples per period, plus white noise
    of SD ``noise`` times the sine's SD (thesis eq. 6.12, Fig. 6.4)."""
    rng = np.random.default_rng(seed)
    t = np.arange(m * n + 1) / n
    y = np.sin(2 * np.pi * t)
    y = y + noise * np.std(y[:-1]) * rng.standard_normal(y.shape)
    return t, y, np.arange(0, m * n + 1, n)


def pattern_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two nominal patterns (thesis Fig. 7.3); 0 if one is flat."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if np.std(a) < 1e-12 or np.std(b) < 1e-12:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])
