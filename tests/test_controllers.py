"""The controller interface, command schedules and laws, and the model registry.

Includes the small example controller of docs/architecture.md (constant stimulation with a
one-parameter table), plugged in as a new model without touching the simulator.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import evaluate, models, presets, sim, taga
from jaxgait.control import commands as cmd
from jaxgait.control.interface import Controller
from jaxgait.core.params import ParamSpec, ParamTable
from jaxgait.muscles.mtu import GEYER7, WANG8
from jaxgait.train import experiments as exps
from jaxgait.train import main as train_main
from jaxgait.train import train
from jaxgait.world import envs

# ------------------------------------------------------------------ the example controller

CONST = ParamTable(
    "const", (ParamSpec("s", 0.05, 0.01, 1.0, "constant stimulation of every muscle"),)
)


def const_init(ctrl, sensors, dt):
    return None  # no state of its own


def const_step(ctrl, p, sensors, state, command, dt):
    stim = jnp.full((2, ctrl.n_muscles), p["s"] * command["gain"], sensors.f_norm.dtype)
    return stim, state


CONSTANT = Controller(
    name="const",
    table=CONST,
    n_muscles=7,
    init=const_init,
    step=const_step,
    commands=(cmd.Command("gain", 1.0, "-", "scales the stimulation"),),
    description="constant stimulation (example of docs/architecture.md)",
)


@pytest.fixture
def const_model():
    models.register(models.planar_spec(CONSTANT))
    yield models.get_model("const")
    models.unregister("const")


def test_example_controller_runs_through_rollout(const_model):
    cfg = sim.SimConfig(duration=0.3)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    f = sim.make_rollout(const_model, cfg, batched=False)
    trace, _, summary, final = f(jnp.asarray([0.3]), env)
    alive = np.asarray(trace.alive)
    # the muscles see the constant stimulation (after the first logged row)
    np.testing.assert_allclose(np.asarray(trace.stim)[1:][alive[1:]], 0.3, rtol=1e-6)
    act = np.asarray(trace.act)
    assert act[-1].mean() > act[0].mean()  # activation rises towards 0.3 (tau = 10 ms)
    assert final.ctrl is None and float(summary.duration) > 0


def test_example_controller_runs_through_train(const_model, tmp_path):
    exp = exps.Experiment(
        name="const_tiny",
        description="example controller",
        model="const",
        optimiser="cmaes",
        init="table",
        particles=4,
        iterations=1,
        duration=0.4,
        stages=None,
        weights=(("distance", 1.0),),
    )
    res = train(exp, out_dir=tmp_path / "run", progress=None, plots=False)
    assert res.best_params.shape == (1,)
    doc = presets.load_preset(tmp_path / "run")
    assert doc[0] == "const" and 0.01 <= doc[1][0] <= 1.0
    # the result evaluates like any preset
    assert evaluate.main([str(tmp_path / "run"), "--duration", "0.3", "--json"]) == 0


def test_controller_must_match_the_muscle_table():
    bad = Controller("bad", CONST, 8, const_init, const_step)
    with pytest.raises(ValueError, match="8 muscles per leg, the muscle table has 7"):
        sim.planar_model(bad, muscles=GEYER7)
    assert sim.planar_model(bad).muscles is WANG8  # the default table of 8 muscles
    with pytest.raises(ValueError, match="9 muscles per leg; no default muscle table"):
        sim.planar_model(Controller("bad9", CONST, 9, const_init, const_step))


# ------------------------------------------------------------------ the registry


@pytest.mark.parametrize("name", models.model_names())
def test_every_registered_model_builds_rolls_out_and_is_listed(name, capsys):
    spec = models.get_spec(name)
    model = models.get_model(name)
    assert models.get_model(name) is model  # one cached instance
    if spec.family == "planar":
        vec = jnp.asarray(spec.table.init, jnp.float32)
        f = sim.make_rollout(model, sim.SimConfig(duration=0.5), batched=False)
        _, _, summary, _ = f(vec, envs.make_env("flat", jax.random.PRNGKey(0)))
        assert float(summary.duration) > 0.05 and np.isfinite(float(summary.distance))
    else:
        state, log = taga.simulate(duration=0.5, sim=model)
        assert float(state.t) == pytest.approx(0.5, abs=1e-3) and bool(log.alive[-1])
    model_flag = next(a for a in evaluate._parser()._actions if "--model" in a.option_strings)
    assert name in model_flag.choices
    assert name in presets.available_models()
    assert train_main(["--list"]) == 0
    listed = capsys.readouterr().out.split("\nmodels ")[1].splitlines()[1:]
    assert any(line.split()[0] == name for line in listed)


def test_unknown_model_lists_the_registered_ones():
    with pytest.raises(KeyError, match="registered: fbl, fblplus, fbl_net, fblplus_net, taga"):
        models.get_model("fbl_minus_typo")


# ------------------------------------------------------------------ schedules and laws


def test_hold_and_linear_schedules_by_hand():
    c = (cmd.Command("a", 1.0), cmd.Command("b", -2.0))
    s = cmd.schedule(c, [(0.0, {"a": 0.5}), (1.0, {"a": 2.5, "b": 4.0})])
    np.testing.assert_allclose(s.at(-1.0), [0.5, -2.0])
    np.testing.assert_allclose(s.at(0.99), [0.5, -2.0])
    np.testing.assert_allclose(s.at(1.0), [2.5, 4.0])
    np.testing.assert_allclose(s.at(7.0), [2.5, 4.0])
    lin = cmd.schedule(c, [(0.0, {"a": 0.5}), (1.0, {"a": 2.5, "b": 4.0})], interp="linear")
    np.testing.assert_allclose(lin.at(0.25), [1.0, -0.5], rtol=1e-6)
    np.testing.assert_allclose(lin.at(3.0), [2.5, 4.0])
    np.testing.assert_allclose(cmd.constant(c, b=3.0).at(5.0), [1.0, 3.0])


def test_schedule_errors_say_what_is_wrong():
    c = (cmd.Command("lean_offset", 0.0),)
    with pytest.raises(cmd.CommandError, match="unknown command.*speed.*takes: lean_offset"):
        cmd.schedule(c, {"speed": 1.0})
    with pytest.raises(cmd.CommandError, match="before the previous knot"):
        cmd.schedule(c, [(1.0, {}), (0.5, {})])
    with pytest.raises(cmd.CommandError, match="not a number"):
        cmd.schedule(c, {"lean_offset": "x"})
    with pytest.raises(cmd.CommandError, match="interp"):
        cmd.schedule(c, {}, interp="cubic")


@pytest.fixture(scope="module")
def fblplus_run():
    model = models.get_model("fblplus")
    _, vec, _ = presets.load_preset("fblplus_walk")
    cfg = sim.SimConfig(duration=0.8, chunk_s=0.4)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    f = jax.jit(lambda c: sim.rollout(model, cfg, jnp.asarray(vec, jnp.float32), env, c))
    return model, f, f(None)


def _leaves_equal(a, b):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_a_schedule_of_the_defaults_changes_nothing(fblplus_run):
    """Bit for bit with one knot; with several knots the command depends on the time, XLA
    compiles the step differently and the rollouts agree to float32 rounding."""
    model, f, ref = fblplus_run
    c = model.controller.commands
    defaults = {x.name: x.default for x in c}
    _leaves_equal(ref, f(cmd.constant(c, **defaults)))
    two = f(cmd.schedule(c, [(0.0, defaults), (0.4, defaults)]))
    np.testing.assert_allclose(np.asarray(two[0].qpos), np.asarray(ref[0].qpos), atol=1e-4)
    assert abs(float(two[2].distance) - float(ref[2].distance)) < 1e-3
    np.testing.assert_array_equal(np.asarray(two[0].alive), np.asarray(ref[0].alive))


def test_a_command_changed_mid_rollout_changes_the_trace_only_after(fblplus_run):
    model, f, _ = fblplus_run
    c = model.controller.commands
    t_switch = 0.3
    # the same compiled program (two knots) for the reference and the switch
    ref = f(cmd.schedule(c, [(0.0, {}), (t_switch, {})]))[0]
    trace = f(cmd.schedule(c, [(0.0, {}), (t_switch, {"lean_offset": 0.1})]))[0]
    t = np.asarray(ref.t)
    before, after = t < t_switch - 1e-6, t > t_switch + 1e-6
    for name in ("qpos", "stim", "act", "grf"):
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(trace, name))
        np.testing.assert_array_equal(a[before], b[before], err_msg=name)
    # the lean reference moved: the hip stimulation differs right after the switch
    assert np.abs(np.asarray(ref.stim)[after] - np.asarray(trace.stim)[after]).max() > 1e-3


def _set_lean(value):
    """A command law that overrides lean_offset with ``value`` and counts its steps."""

    def init(law, sensors, command):
        return jnp.zeros((), jnp.int32)

    def step(law, state, sensors, command, dt):
        return command.at[0].set(law.settings), state + 1

    return cmd.CommandLaw("set_lean", init, step, settings=value)


def test_a_command_law_runs_inside_the_step():
    model = models.get_model("fbl")
    _, vec, _ = presets.load_preset("fbl_walk")
    cfg = sim.SimConfig(duration=0.2)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    p = jnp.asarray(vec, jnp.float32)
    law = jax.jit(lambda: sim.rollout(model, cfg, p, env, command_law=_set_lean(0.05)))()
    sch = jax.jit(lambda c: sim.rollout(model, cfg, p, env, c))(
        cmd.constant(model.controller.commands, lean_offset=0.05)
    )
    _leaves_equal(law[0], sch[0])
    # one law step per physics step (the rollout runs on to its chunk end)
    assert int(law[3].command_state) == round(float(law[3].t) / model.dt)


@pytest.mark.slow
def test_schedules_vmap_like_environments():
    model = models.get_model("fbl")
    _, vec, _ = presets.load_preset("fbl_walk")
    f = sim.make_rollout(model, sim.SimConfig(duration=0.2), batched=True)
    c = model.controller.commands
    batch = jax.tree.map(
        lambda *x: jnp.stack(x), cmd.constant(c, lean_offset=0.0), cmd.constant(c, lean_offset=0.2)
    )
    p = jnp.asarray(np.stack([vec, vec]), jnp.float32)
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), 2))
    trace = f(p, env, batch)[0]
    none = f(p, env)[0]
    np.testing.assert_array_equal(np.asarray(trace.qpos[0]), np.asarray(none.qpos[0]))
    assert not np.array_equal(np.asarray(trace.stim[1]), np.asarray(none.stim[1]))


def test_taga_drive_as_a_schedule():
    p = taga.TagaParams(u0=5.5)
    _, ref = taga.simulate(p, 1.0)
    _, same = taga.simulate(p, 1.0, commands=cmd.constant(taga.sim.COMMANDS, u0=5.5))
    _leaves_equal(ref, same)
    step = cmd.schedule(taga.sim.COMMANDS, [(0.0, {"u0": 5.5}), (0.5, {"u0": 8.0})])
    _, log = taga.simulate(p, 1.0, commands=step)
    u0 = np.asarray(log.u0)
    np.testing.assert_array_equal(u0[:50], 5.5)
    np.testing.assert_array_equal(u0[50:], 8.0)
    np.testing.assert_array_equal(np.asarray(log.qpos)[:50], np.asarray(ref.qpos)[:50])
