"""SHA-256 digests of rollouts, to show that a refactor changes nothing.

Records a digest of every array of ``Trace``, ``Events``, ``Summary`` and the final state of:
``fbl_walk`` on flat and on wavy ground (batched), FBL+ with its extra rules neutral and
active (batched), one unbatched rollout, a short gradient window (loss and gradient), a 2 s
Taga rollout and a 2-iteration ``quickstart`` training (its ``best.json`` and its history
without the timing columns).  Run it before and after a change on the same machine and
compare::

    ./jg python benchmarks/rollout_digests.py --out /tmp/before.json
    ... change ...
    ./jg python benchmarks/rollout_digests.py --out /tmp/after.json --compare /tmp/before.json

Fields are keyed by canonical names: where a refactor renames or moves a state field,
:data:`ALIASES` maps the new path to the old one, so that the comparison is by value.
The script finds the API through ``_api()``, which knows both the flat and the layered
package layout.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

#: renamed state fields: new path segment -> canonical (older) one, applied to every key.
#: The controller interface split ``SimState.reflex`` into the shared gait-phase state
#: ``gait`` (load, stance, td_time, theta_to) and the controller's own state ``ctrl`` (for
#: the reflex controllers, the delay line that was ``reflex.lines``).
ALIASES: dict[str, str] = {".gait.": ".reflex.", ".ctrl.": ".reflex.lines."}

TIMING_COLUMNS = (
    "wall_s",
    "elapsed_s",
    "time_s",
    "eta_s",
    "rollouts_per_s",
    "seconds",
    "env_steps_per_s",
)


def _digest(x) -> str:
    a = np.ascontiguousarray(np.asarray(x))
    h = hashlib.sha256()
    h.update(str(a.dtype).encode() + str(a.shape).encode())
    h.update(a.tobytes())
    return h.hexdigest()[:16]


def _canonical(path: str) -> str:
    for new, old in ALIASES.items():
        path = path.replace(new, old)
    return path


def _tree_digests(prefix: str, tree) -> dict[str, str]:
    out = {}
    for kp, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]:
        name = "".join(
            f".{k.name}" if hasattr(k, "name") else f".{getattr(k, 'key', getattr(k, 'idx', k))}"
            for k in kp
        )
        out[_canonical(prefix + name)] = _digest(leaf)
    return out


def _api():
    """(sim, get_model, presets, envs, lift_fbl, OFF, gradient, train, simulate, TagaParams)."""
    from jaxgait import presets, sim
    from jaxgait.taga import simulate
    from jaxgait.taga.model import TagaParams

    try:  # layered layout
        from jaxgait.control.fblplus import OFF, lift_fbl
        from jaxgait.optim import gradient
        from jaxgait.train import train
        from jaxgait.world import envs
    except ImportError:
        from jaxgait.reflex_plus import OFF, lift_fbl

        from jaxgait import envs, gradient
        from jaxgait.train import train
    try:
        from jaxgait.models import get_model
    except ImportError:
        get_model = sim.make_model
    return sim, get_model, presets, envs, lift_fbl, OFF, gradient, train, simulate, TagaParams


def _rollout_digests(prefix, out) -> dict[str, str]:
    trace, events, summary, final = out
    d = {}
    d.update(_tree_digests(f"{prefix}/trace", trace))
    d.update(_tree_digests(f"{prefix}/events", events))
    d.update(_tree_digests(f"{prefix}/summary", summary))
    d.update(_tree_digests(f"{prefix}/final", final))
    return d


def run_all(seconds: float = 3.0) -> dict[str, str]:
    sim, get_model, presets, envs, lift_fbl, OFF, gradient, train, simulate, TagaParams = _api()
    d: dict[str, str] = {}
    _, vec, _ = presets.load_preset("fbl_walk")
    vec = np.asarray(vec, np.float32)
    fbl = get_model("fbl")
    cfg = sim.SimConfig(duration=seconds)

    # fbl_walk flat and wavy, batched (2 lanes: the preset and a copy scaled by 1 + 1e-3)
    params = jnp.asarray(np.stack([vec, vec * np.float32(1.001)]))
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    f = sim.make_rollout(fbl, cfg, batched=True)
    for env_name in ("flat", "wavy"):
        env = envs.make_env_batch(env_name, keys)
        d.update(_rollout_digests(f"fbl_{env_name}", jax.device_get(f(params, env))))

    # FBL+ neutral (its shipped preset) and active, batched
    _, vplus, _ = presets.load_preset("fblplus_walk")
    active = {"kp_HFL": 1.5, "kd_HFL": 0.2, "kp_GLU": 1.5, "kp_VAS": 1.0, "d_sw_end": -0.5}
    pplus = jnp.asarray(np.stack([np.asarray(vplus), lift_fbl(vec, active)]), jnp.float32)
    fp = sim.make_rollout(get_model("fblplus"), cfg, batched=True)
    d.update(
        _rollout_digests("fblplus", jax.device_get(fp(pplus, envs.make_env_batch("flat", keys))))
    )

    # one unbatched rollout
    f1 = sim.make_rollout(fbl, sim.SimConfig(duration=2.0), batched=False)
    env1 = envs.make_env("flat", jax.random.PRNGKey(1))
    d.update(_rollout_digests("unbatched", jax.device_get(f1(jnp.asarray(vec), env1))))

    # a short gradient window
    wcfg = gradient.WindowConfig(warmup_s=0.5, window_s=0.2, segment_s=0.1)
    warm, _, _ = wcfg.steps(fbl.dt)
    s0 = gradient.start_state(fbl, jnp.asarray(vec), env1, warm)
    (loss, aux), g = gradient.loss_and_grad(fbl, wcfg, jnp.asarray(vec), env1, s0)
    d.update(_tree_digests("gradient/start", s0))
    d["gradient/loss"] = _digest(loss)
    d["gradient/grad"] = _digest(g)
    d.update(_tree_digests("gradient/aux", aux))

    # a 2 s Taga rollout
    state, log = simulate(TagaParams(u0=5.5), 2.0)
    d.update(_tree_digests("taga/final", state))
    d.update(_tree_digests("taga/log", log))

    # a 2-iteration quickstart training
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "qs"
        train("quickstart", out_dir=out, progress=None, max_iterations=2, plots=False)
        best = json.loads((out / "best.json").read_text())
        d["quickstart/best.json"] = hashlib.sha256(
            json.dumps(best, sort_keys=True).encode()
        ).hexdigest()[:16]
        hist = out / "history.csv"
        if hist.exists():
            with hist.open() as fh:
                rows = list(csv.DictReader(fh))
            for r in rows:
                for c in list(r):
                    if c in TIMING_COLUMNS or c.endswith("_s") and "time" in c:
                        del r[c]
            d["quickstart/history"] = hashlib.sha256(
                json.dumps(rows, sort_keys=True).encode()
            ).hexdigest()[:16]
    return d


def compare(new: dict, old: dict) -> int:
    same = sorted(k for k in new if k in old and new[k] == old[k])
    diff = sorted(k for k in new if k in old and new[k] != old[k])
    only_new = sorted(set(new) - set(old))
    only_old = sorted(set(old) - set(new))
    print(
        f"identical: {len(same)}  different: {len(diff)}  new only: {len(only_new)}  "
        f"old only: {len(only_old)}"
    )
    for k in diff:
        print(f"  DIFFERENT {k}: {old[k]} -> {new[k]}")
    for k in only_new:
        print(f"  new only  {k}")
    for k in only_old:
        print(f"  old only  {k}")
    return 0 if not diff and not only_old else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="JSON file of the digests")
    ap.add_argument("--compare", type=Path, help="earlier digests to compare with")
    ap.add_argument("--seconds", type=float, default=3.0, help="rollout length [s]")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    d = run_all(a.seconds)
    a.out.write_text(json.dumps(d, indent=1, sort_keys=True) + "\n")
    print(
        f"{len(d)} digests in {time.perf_counter() - t0:.0f} s -> {a.out} "
        f"(jax {jax.__version__}, {os.cpu_count()} cpus)"
    )
    if a.compare:
        return compare(d, json.loads(a.compare.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
