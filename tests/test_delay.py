"""Neural delays: an impulse arrives exactly 5 / 10 / 20 ms later."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.control import fbl as reflex
from jaxgait.control.delay import delay_init, delay_step, delay_taps, steps_for
from jaxgait.control.fbl import FBL


@pytest.mark.parametrize("delay", [0.005, 0.010, 0.020])
def test_delay_line_impulse(delay):
    dt = 0.0005
    n = steps_for(delay, dt)
    line = delay_init(n, jnp.zeros(()))
    outs = []
    for k in range(100):
        out, line = delay_step(line, jnp.asarray(1.0 if k == 7 else 0.0))
        outs.append(float(out))
    assert np.nonzero(outs)[0].tolist() == [7 + n]
    assert n * dt == pytest.approx(delay)


def test_tapped_line_impulse_arrives_at_each_tap():
    taps = (10, 20, 40)  # 5 / 10 / 20 ms at 0.5 ms
    line = delay_init(max(taps), jnp.zeros(2))
    outs = []
    for k in range(120):
        x = jnp.asarray([1.0, 2.0]) if k == 11 else jnp.zeros(2)
        out, line = delay_taps(line, x, taps)
        outs.append(np.asarray(out))
    outs = np.array(outs)  # (time, tap, 2)
    for j, n in enumerate(taps):
        assert np.nonzero(outs[:, j, 0])[0].tolist() == [11 + n]
        assert outs[11 + n, j].tolist() == [1.0, 2.0]
    with pytest.raises(ValueError, match="taps"):
        delay_taps(line, jnp.zeros(2), (0, 40))
    with pytest.raises(ValueError, match="taps"):
        delay_taps(line, jnp.zeros(2), (41,))


def test_delay_must_be_whole_steps():
    with pytest.raises(ValueError, match="whole number"):
        steps_for(0.005, 0.0003)


def test_reflex_delays_per_muscle_group():
    """A force impulse on every muscle reaches hip / knee / ankle stimulations 5/10/20 ms later."""
    dt = 0.0005
    n = max(reflex.delay_taps_for(reflex.ReflexSettings(), dt))
    zero = jnp.zeros((2, reflex.N_SENSORS))
    lines = delay_init(n, zero.at[:, reflex.S_STANCE].set(1.0))
    p = FBL.unpack(jnp.asarray(FBL.init))
    base = zero.at[:, reflex.S_STANCE].set(1.0)
    kick = base.at[:, reflex.S_F].set(1.0)
    stims = []
    for k in range(60):
        s_in = kick if k == 3 else base
        stim, lines = reflex.delayed_stimulation(p, lines, s_in)
        stims.append(np.asarray(stim[0]))
    stims = np.array(stims)
    changed = np.abs(stims - stims[0]).max(axis=0) > 0
    first = [int(np.argmax(np.abs(stims[:, m] - stims[0, m]) > 0)) for m in range(7)]
    # force-feedback muscles in stance: VAS (knee, 10 ms), GAS and SOL (ankle, 20 ms), and TA
    # via the SOL force (20 ms)
    assert changed[reflex.VAS] and first[reflex.VAS] == 3 + 20
    assert changed[reflex.SOL] and first[reflex.SOL] == 3 + 40
    assert changed[reflex.GAS] and first[reflex.GAS] == 3 + 40
    assert changed[reflex.TA] and first[reflex.TA] == 3 + 40


def test_reflex_delay_hip_group():
    dt = 0.0005
    base = jnp.zeros((2, reflex.N_SENSORS))  # swing: GLU/HAM force feedback
    lines = delay_init(max(reflex.delay_taps_for(reflex.ReflexSettings(), dt)), base)
    p = FBL.unpack(jnp.asarray(FBL.init))
    out = []
    for k in range(30):
        stim, lines = reflex.delayed_stimulation(
            p, lines, base.at[:, reflex.S_F].set(1.0) if k == 2 else base
        )
        out.append(float(stim[0, reflex.GLU]))
    out = np.array(out)
    assert int(np.argmax(np.abs(out - out[0]) > 0)) == 2 + 10
