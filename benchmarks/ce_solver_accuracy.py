"""Accuracy of the implicit CE solve per step against its converged solution (a benchmark).

Drives the seven Geyer muscles of one leg with 1.2 s of gait-like joint motion and
stimulation (float32, dt = 0.5 ms), stepping with a well-converged solve (12 Newton
iterations), and from each of those states takes one step with k = 1, 2, 3 iterations.  It
prints the per-step CE-length error |l_ce,k - l_ce,12| / l_opt: how far the default
(k = 3) and cheaper settings are from the backward-Euler step they approximate.  Usage::

    python benchmarks/ce_solver_accuracy.py
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import muscle as mu
from jaxgait.muscle import GEYER7


def main():
    table, dt, n = GEYER7, 5e-4, 2400
    t = np.arange(n) * dt
    w = 2 * np.pi / 1.1
    phi_deg = np.stack(
        [165 + 20 * np.sin(w * t), 160 + 25 * np.sin(w * t + 1.0), 90 + 12 * np.sin(w * t + 2.0)],
        -1,
    )
    l_mtu = mu.mtu_length(table, jnp.asarray(np.radians(phi_deg), jnp.float32))
    phase = w * t[:, None] + np.arange(7)[None] * 0.9
    stim = jnp.asarray(0.01 + 0.99 * np.clip(np.sin(phase), 0, 1) ** 3, jnp.float32)
    ref = functools.partial(mu.muscle_step, newton_iters=12)
    ks = (1, 2, 3)

    def f(s, x):
        s1, _ = ref(table, s, x[0], x[1], dt)
        errs = [mu.muscle_step(table, s, x[0], x[1], dt, newton_iters=k)[0].l_ce for k in ks]
        return s1, (jnp.stack(errs) - s1.l_ce, s1.l_ce - s.l_ce)

    s0 = mu.init_muscle_state(table, l_mtu[0])
    _, (err, dl) = jax.jit(lambda s: jax.lax.scan(f, s, (stim, l_mtu)))(s0)
    lopt = np.asarray(table.l_opt)
    err = np.abs(np.asarray(err)) / lopt
    print(f"median |dl_ce| per step: {np.median(np.abs(np.asarray(dl)) / lopt):.1e} l_opt")
    for i, k in enumerate(ks):
        e = err[:, i]
        worst = np.unravel_index(np.argmax(e), e.shape)
        print(
            f"{k} Newton iteration(s): max error {e.max():.1e} l_opt "
            f"({table.names[worst[1]]} at t = {worst[0] * dt:.3f} s), "
            f"steps above 1e-6 l_opt: {100 * (e > 1e-6).mean():.1f} %, "
            f"above 1e-5: {100 * (e > 1e-5).mean():.1f} %"
        )


if __name__ == "__main__":
    main()
