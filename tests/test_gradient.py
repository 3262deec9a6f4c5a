"""Gradient refinement (jaxgait.optim.gradient): autodiff vs finite differences, and refinement.

Everything runs in float64 (``jax.enable_x64`` for this module only) and shares one compiled
window program: 0.05 s checkpointed segments, an outer scan of up to ``MAX_SEG`` of them, the
window length traced (compiling the reverse pass of the full model takes 1.5-3 minutes on this
CPU; it is compiled once).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import sim
from jaxgait.optim import gradient as gr

MAX_SEG = 20  # up to 1 s windows
OBJECTIVE = "energy"


@pytest.fixture(scope="module")
def setup():
    from jaxgait.train import get_model, resolve_init
    from jaxgait.world.envs import make_env

    with jax.enable_x64(True):
        model = get_model("fbl")
        vec = jnp.asarray(resolve_init("fbl_walk", model.table), jnp.float64)
        env = make_env("flat", jax.random.PRNGKey(0))
        yield model, vec, env


def _loss_grad(model, cfg, p, env, s0):
    return gr.loss_and_grad(model, cfg, p, env, s0, n_segments=1, max_segments=MAX_SEG)


@pytest.mark.slow
def test_gradient_is_finite_and_matches_finite_differences(setup):
    """0.05 s from the initial posture (right stance, no phase switch): AD == central FD."""
    model, p, env = setup
    table = model.table
    with jax.enable_x64(True):
        cfg = gr.WindowConfig(window_s=0.05, segment_s=0.05, warmup_s=0.0, objective=OBJECTIVE)
        s0 = sim.initial_state(model, p, env, sim.SimConfig(duration=1e9))
        (loss, aux), g = _loss_grad(model, cfg, p, env, s0)
        g = np.asarray(g)
        assert loss.dtype == jnp.float64 and np.all(np.isfinite(g))
        assert not bool(aux["fell"]) and float(aux["dx_m"]) > 0.03
        # parameters acting through the muscle dynamics (stimulation -> activation -> force)
        for name in ("S0_SOL", "S0_VAS", "S0_GAS", "G_SOL"):
            i = table.index(name)
            h = 1e-6 * (table.upper[i] - table.lower[i])
            e = jnp.zeros_like(p).at[i].set(h)
            lp = float(_loss_grad(model, cfg, p + e, env, s0)[0][0])
            lm = float(_loss_grad(model, cfg, p - e, env, s0)[0][0])
            fd = (lp - lm) / (2 * h)
            assert abs(g[i] - fd) <= 5e-3 * abs(fd) + 1e-8, (name, g[i], fd)
        assert abs(g[table.index("S0_SOL")]) > 1e-2  # the prestimulation costs energy


def test_window_config_checks():
    with pytest.raises(gr.GradientError, match="valid objectives: energy, angles"):
        gr.WindowConfig(objective="speed")
    with pytest.raises(gr.GradientError, match="window_s"):
        gr.WindowConfig(window_s=0.0)
    with pytest.raises(gr.GradientError, match="warmup_s"):
        gr.WindowConfig(warmup_s=-1.0)
    cfg = gr.WindowConfig(window_s=1.0, segment_s=0.05, warmup_s=3.0, log_every=10)
    assert cfg.steps(0.0005) == (6000, 100, 10 * 2)


def test_segment_count_checks(setup):
    model, p, env = setup
    with pytest.raises(gr.GradientError, match="n_segments"):
        gr.loss_and_grad(model, gr.WindowConfig(), p, env, None, n_segments=5, max_segments=2)


@pytest.mark.slow
def test_refinement_improves_the_window_objective_without_falling(setup):
    """Adam on a 1 s window after 3 s of walking: the objective drops, the gait still walks."""
    model, p, env = setup
    with jax.enable_x64(True):
        cfg = gr.WindowConfig(window_s=1.0, segment_s=0.05, warmup_s=3.0, objective=OBJECTIVE)
        res = gr.refine(
            model,
            p,
            env,
            cfg,
            steps=6,
            learning_rate=0.002,
            check_s=10.0,
            max_segments=MAX_SEG,
        )
    lower, upper = model.table.lower, model.table.upper
    assert np.all(res.params >= lower) and np.all(res.params <= upper)
    assert np.all(np.isfinite(res.losses)) and np.all(np.isfinite(res.grad_norms))
    assert res.losses[-1] < res.losses[0]
    assert res.fell_initial is False and res.fell_final is False
    assert not np.allclose(res.params, res.initial_params)
