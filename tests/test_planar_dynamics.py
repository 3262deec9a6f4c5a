"""The planar tree's equations of motion (``SimConfig(dynamics="planar")``) against MJX's
composite-rigid-body and recursive Newton-Euler passes, against energy and gravity computed
independently, and through the step, the experiments and the presets."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, sim
from jaxgait.body.planar import load_body
from jaxgait.train.experiments import Experiment, ExperimentError, get_experiment
from jaxgait.world import envs


@pytest.fixture(autouse=True)
def _x64():
    with jax.enable_x64(True):
        yield


def _state(seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.2, 1.2, 9)
    q[:2] = rng.uniform(-2.0, 2.0, 2)  # root x, z [m]
    return jnp.asarray(q), jnp.asarray(rng.normal(0.0, 3.0, 9))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_mass_and_bias_equal_mjx(seed):
    """M and the smooth force equal MJX's at any state, in float64, to rounding."""
    model = models.get_model("fbl")
    q, v = _state(seed)
    f = jnp.asarray(np.random.default_rng(seed + 1).normal(0.0, 50.0, 9))
    M_mjx, s_mjx = model.mass_and_forces(q, v, f)
    M, s = model.mass_and_forces_of("planar", q, v, f)
    np.testing.assert_allclose(np.asarray(M), np.asarray(M_mjx), rtol=0, atol=1e-11)
    np.testing.assert_allclose(np.asarray(s), np.asarray(s_mjx), rtol=0, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_mass_matrix_is_kinetic_energy_and_bias_at_rest_is_gravity(seed):
    """Independent of MJX: q_d^T M q_d / 2 is the bodies' kinetic energy (centre-of-mass
    velocities by forward-mode AD of the kinematics, plus I w^2 / 2), M is symmetric
    positive definite, and at rest the bias is the gradient of the potential energy."""
    body = load_body()
    q, v = _state(seed)
    M, bias0 = body.mass_and_bias(q, jnp.zeros_like(v))
    m = body.mj_model
    mass, inertia = body.mass[1:], m.body_inertia[1:, 1]

    def coms(q):
        o, a = body.frames(q)
        return body._local_to_world(o[1:], a[1:], jnp.asarray(body.ipos[1:])), a[1:]

    (_, _), (vc, w) = jax.jvp(coms, (q,), (v,))
    kinetic = 0.5 * np.sum(mass * np.sum(np.asarray(vc) ** 2, -1)) + 0.5 * np.sum(
        inertia * np.asarray(w) ** 2
    )
    np.testing.assert_allclose(0.5 * float(v @ M @ v), kinetic, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(M), np.asarray(M).T, atol=1e-13)
    assert np.all(np.linalg.eigvalsh(np.asarray(M)) > 0)
    potential = lambda q: 9.81 * jnp.sum(jnp.asarray(mass) * coms(q)[0][:, 1])
    np.testing.assert_allclose(np.asarray(bias0), np.asarray(jax.grad(potential)(q)), atol=1e-10)


def test_bias_is_the_velocity_product_of_the_lagrangian():
    """C(q, q_d) q_d from the Lagrangian, M_dot q_d - dT/dq, by AD of the kinetic energy."""
    body = load_body()
    q, v = _state(3)
    kinetic = lambda q, v: 0.5 * v @ body.mass_and_bias(q, v)[0] @ v
    M_dot_v = jax.jvp(lambda q: body.mass_and_bias(q, v)[0] @ v, (q,), (v,))[1]
    coriolis = M_dot_v - jax.grad(kinetic, argnums=0)(q, v)
    _, bias = body.mass_and_bias(q, v)
    _, bias0 = body.mass_and_bias(q, jnp.zeros_like(v))
    np.testing.assert_allclose(np.asarray(bias - bias0), np.asarray(coriolis), atol=1e-9)


def test_passive_elements_are_refused():
    """Joint damping (which MJX's passive pass would add) is not modelled by the planar tree."""
    body = load_body()
    body.mj_model.dof_damping[4] = 1.0
    with pytest.raises(ValueError, match="joint damping.*dynamics='mjx'"):
        body.mass_and_bias(jnp.zeros(9), jnp.zeros(9))


def test_rollouts_agree_in_float64():
    """One second of fbl_walk with either dynamics: the same motion to float64 rounding."""
    model = models.get_model("fbl")
    env = jax.tree.map(
        lambda x: jnp.asarray(x, jnp.float64) if x.dtype == jnp.float32 else x,
        envs.make_env(envs.get_env_config("flat"), jax.random.PRNGKey(0)),
    )
    params = jnp.asarray(model.table.init, jnp.float64)
    out = {}
    for dyn in sim.DYNAMICS:
        cfg = sim.SimConfig(duration=1.0, dynamics=dyn)
        trace, _, summary, _ = jax.jit(lambda p, e, cfg=cfg: sim.rollout(model, cfg, p, e))(
            params, env
        )
        out[dyn] = (np.asarray(trace.qpos), float(summary.distance))
    np.testing.assert_allclose(out["planar"][0], out["mjx"][0], rtol=0, atol=1e-9)
    assert out["planar"][1] == pytest.approx(out["mjx"][1], abs=1e-9)


def test_sim_config_and_experiment_check_the_dynamics():
    with pytest.raises(ValueError, match="dynamics must be one of"):
        sim.SimConfig(dynamics="bullet")
    with pytest.raises(ExperimentError, match="invalid dynamics='bullet'"):
        dataclasses.replace(get_experiment("quickstart"), dynamics="bullet")


def test_new_runs_are_planar_and_old_configs_mjx():
    """A registered experiment runs the planar tree and says so in its config; a config
    written without the key (every run before the option) loads as MJX's and writes back
    unchanged, so resuming it runs what it ran."""
    exp = get_experiment("exp3")
    assert exp.dynamics == "planar" and exp.to_dict()["dynamics"] == "planar"
    old = exp.to_dict()
    del old["dynamics"]
    loaded = Experiment.from_dict(json.loads(json.dumps(old)))
    assert loaded.dynamics == "mjx"
    assert loaded.to_dict() == old
    assert Experiment.from_dict(exp.to_dict()).dynamics == "planar"
