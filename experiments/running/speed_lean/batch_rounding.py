"""Does a preset's rollout survive the float32 rounding of other batch layouts?

Rolls identical copies of a preset out on flat ground in batches of the given sizes (``vmap``;
each batch size is its own XLA program, whose vectorised code can round each lane a little
differently) and prints every lane's duration (experiments/running/README.md, "A speed
regulator").  Usage::

    ./jg python experiments/running/speed_lean/batch_rounding.py fblplus_run_2p0 1,2,3,4,5,8,16
"""

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.presets import load_preset, preset_dynamics
from jaxgait.world import envs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset")
    ap.add_argument("batches", help="comma-separated batch sizes, e.g. 1,2,3,4")
    ap.add_argument("--duration", type=float, default=30.0)
    a = ap.parse_args(argv)
    _, base, doc = load_preset(a.preset)
    model = models.get_model(doc["model"])
    pose = doc.get("pose", sim.SimConfig.pose)
    cfg = sim.SimConfig(duration=a.duration, v0=doc["v0"], pose=pose, dynamics=preset_dynamics(doc))
    run = sim.make_rollout(model, cfg)
    for b in (int(x) for x in a.batches.split(",")):
        params = jnp.tile(jnp.asarray(base, jnp.float32), (b, 1))
        env = envs.make_env_batch("flat", jnp.tile(jax.random.PRNGKey(0), (b, 1)))
        summary = run(params, env)[2]
        durations = [round(float(d), 1) for d in np.asarray(summary.duration)]
        print(a.preset, "batch", b, "durations [s]", durations, flush=True)


if __name__ == "__main__":
    main()
