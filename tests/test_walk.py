"""The shipped walking preset walks, and its gait measures converge with the time step."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, sim
from jaxgait.analysis.measures import compute_measures
from jaxgait.presets import load_preset
from jaxgait.world import envs


def _walk(vec, duration, timestep=None, model="fbl", v0=sim.SimConfig.v0):
    model = models.get_model(model, timestep)
    cfg = sim.SimConfig(duration=duration, chunk_s=1.0, v0=v0)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    tr, ev, sm, _ = sim.make_rollout(model, cfg, batched=False)(jnp.asarray(vec, jnp.float32), env)
    return {k: float(v) for k, v in compute_measures(tr, ev, sm, skip=2).items() if v.ndim == 0}


@pytest.fixture(scope="module")
def fbl_walk():
    model, vec, doc = load_preset("fbl_walk")
    assert model == "fbl"
    return vec


def test_fbl_walk_walks_20s_on_flat_ground(fbl_walk):
    m = _walk(fbl_walk, 20.0)
    assert not m["fell"]
    assert m["duration_s"] == pytest.approx(20.0, abs=0.01)
    assert 1.1 <= m["mean_speed_mps"] <= 1.5
    assert m["n_steps"] >= 20


@pytest.mark.slow
@pytest.mark.parametrize("name", ["exp1_walk", "exp3_walk", "exp7a_walk"])
def test_full_size_reproduction_presets_walk_20s_on_flat_ground(name):
    """The best gaits of the full-size exp1, exp3 and exp7a runs, shipped as presets, walk on flat
    ground near the thesis's 1.3 m/s (experiments/full/README.md: 60 s each)."""
    model, vec, doc = load_preset(name)
    assert model == "fbl" and doc["experiment"] == name.removesuffix("_walk")
    m = _walk(vec, 20.0)
    assert not m["fell"] and m["duration_s"] == pytest.approx(20.0, abs=0.01)
    assert 1.2 <= m["mean_speed_mps"] <= 1.45 and m["n_steps"] >= 20


def _exp3_polish(start: str, polished: str) -> tuple[dict, dict]:
    """20 s measures of a reference gait and of an exp3 CMA-ES polish (an FBL preset of exp3)."""
    _, before, _ = load_preset(start)
    model, vec, doc = load_preset(polished)
    assert model == "fbl" and doc["experiment"] == "exp3"
    return _walk(before, 20.0), _walk(vec, 20.0)


@pytest.mark.slow
def test_exp3_walk_refined_walks_more_economically_than_exp3_walk():
    """The CMA-ES refinement of exp3's best in its energy stage walks 20 s near 1.3 m/s with
    C_angles still above 0.8 and less energy per metre than the gait it started from
    (experiments/full/README.md, "exp3 refined by CMA-ES": 331 against 377 J/m over 60 s)."""
    m0, m = _exp3_polish("exp3_walk", "exp3_walk_refined")
    assert not m["fell"] and 1.25 <= m["mean_speed_mps"] <= 1.4 and m["c_angles"] > 0.8
    assert m["energy_J_per_m"] < 0.95 * m0["energy_J_per_m"]


@pytest.mark.slow
def test_exp3_walk_economy_walks_on_less_energy_than_the_refined_gait():
    """The 80 m-horizon polish of exp3's best walks 20 s near 1.3 m/s on less energy per metre
    than ``exp3_walk_refined`` with C_angles at the energy stage's threshold (0.8, to 0.02)
    (experiments/full/README.md, "A third 80 m pass": 303 against 331 J/m over 60 s)."""
    m_ref, m = _exp3_polish("exp3_walk_refined", "exp3_walk_economy")
    assert not m["fell"] and 1.25 <= m["mean_speed_mps"] <= 1.4 and m["c_angles"] > 0.78
    assert m["energy_J_per_m"] < 0.95 * m_ref["energy_J_per_m"]


@pytest.mark.slow
def test_exp3_walk_efficient_meets_exp3s_energy_and_angle_targets():
    """exp1's economical gait polished in exp3's objective walks 20 s near 1.3 m/s with
    C_angles above 0.8 on at most a human's 210 J/m, under 0.7 of ``exp3_walk_economy``'s
    energy per metre over the same 20 s (experiments/full/README.md, "exp3 from exp1's
    economical gait": 156 against 303 J/m over 60 s)."""
    m_eco, m = _exp3_polish("exp3_walk_economy", "exp3_walk_efficient")
    assert not m["fell"] and 1.2 <= m["mean_speed_mps"] <= 1.4 and m["c_angles"] > 0.8
    assert m["energy_J_per_m"] <= 210.0
    assert m["energy_J_per_m"] < 0.7 * m_eco["energy_J_per_m"]


@pytest.mark.slow
def test_exp7a_walk_wavy_walks_on_flat_ground_and_further_up_the_wavy_course():
    """The wavy-ground polish of exp7a's best walks 20 s on flat ground near 1.3 m/s, and on the
    robustness command's first three wavy grounds passes structures of 5 % and more, steeper on
    average than ``exp7a_walk`` (experiments/full/README.md, "exp7a polished for the wavy
    ground": 7.38 against 3.55 % over 10 seeds)."""
    from jaxgait.analysis.robustness import RobustnessConfig, walk_tests

    model = models.get_model("fbl")
    _, base, _ = load_preset("exp7a_walk")
    name, vec, doc = load_preset("exp7a_walk_wavy")
    assert name == "fbl" and doc["source"] == "experiments/full/exp7a_wavy80"
    m = _walk(vec, 20.0)
    assert not m["fell"] and 1.15 <= m["mean_speed_mps"] <= 1.45
    rcfg = RobustnessConfig(seeds=3)
    new = walk_tests(model, vec, rcfg, tests=("wavy",))["max_slope_pct_seeds"]
    old = walk_tests(model, base, rcfg, tests=("wavy",))["max_slope_pct_seeds"]
    assert min(new) >= 5.0 and np.mean(new) > np.mean(old)


@pytest.mark.slow
def test_fblplus_fastwalk_walks_20s_fast_with_double_stance_and_no_flight():
    """exp5's best (the start of fblplus_run) walks 20 s from its own v0 above 2.2 m/s, and is a
    walk: double stance, no flight (experiments/full/README.md)."""
    model, vec, doc = load_preset("fblplus_fastwalk")
    assert model == "fblplus" and doc["v0"] == 2.5
    m = _walk(vec, 20.0, model="fblplus", v0=doc["v0"])
    assert not m["fell"] and m["mean_speed_mps"] > 2.2
    assert m["double_stance_fraction"] > 0.05 and m["flight_fraction"] == 0.0


@pytest.mark.slow
def test_fblplus_run_2p0_runs_20s_with_flight_and_regulated_speed():
    """The regulated FBL+ runner runs 20 s from its v0 (2.5 m/s) at 2.0 +- 0.1 m/s with flight
    phases and no double stance; with its speed regulator off (k_vp = k_vi = 0) the same gains
    slow down (experiments/running/README.md, "A speed regulator": the unregulated runner
    slows to a fall within 16 s)."""
    model, vec, doc = load_preset("fblplus_run_2p0")
    assert model == "fblplus_bal_run_sr" and doc["v0"] == 2.5
    m = _walk(vec, 20.0, model=model, v0=doc["v0"])
    assert not m["fell"] and abs(m["mean_speed_mps"] - 2.0) < 0.1
    assert m["flight_fraction"] > 0.15 and m["double_stance_fraction"] < 0.01
    table = models.get_spec(model).table
    off = table.pack({"k_vp": 0.0, "k_vi": 0.0}, base=vec)
    m_off = _walk(off, 20.0, model=model, v0=doc["v0"])
    assert m_off["fell"] or m_off["mean_speed_mps"] < m["mean_speed_mps"] - 0.2


@pytest.mark.slow
def test_fblplus_push_run_runs_in_any_batch_layout():
    """The push-tolerant FBL+ runner runs 20 s with flight phases and no double stance both
    alone and as every lane of a batch of 3 identical copies, the layout whose float32
    rounding tips `fblplus_run_2p0` over at 6.7 s (experiments/running/README.md, "Runners
    robust to rounding")."""
    model_name, vec, doc = load_preset("fblplus_push_run_1p8")
    assert model_name == "fblplus_bal_run_sr"
    m = _walk(vec, 20.0, model=model_name, v0=doc["v0"])
    assert not m["fell"] and 1.7 <= m["mean_speed_mps"] <= 1.95
    assert m["flight_fraction"] > 0.15 and m["double_stance_fraction"] < 0.01
    run = sim.make_rollout(models.get_model(model_name), sim.SimConfig(duration=20.0, v0=doc["v0"]))
    params = jnp.tile(jnp.asarray(vec, jnp.float32), (3, 1))
    env = envs.make_env_batch("flat", jnp.tile(jax.random.PRNGKey(0), (3, 1)))
    summary = run(params, env)[2]
    assert not bool(summary.fell.any())
    assert [round(float(d), 1) for d in summary.duration] == [20.0, 20.0, 20.0]


def test_fbl_humanlike_walks_20s_without_the_forefoot_slap():
    """The human-like preset walks 20 s at 1.2-1.4 m/s, its stance GRF peaks under 2.5 BW
    (fbl_walk's forefoot slaps to 3.7-4.9 BW) and its vertical GRF correlates with Winter's."""
    model, vec, _ = load_preset("fbl_humanlike")
    assert model == "fbl"
    m = _walk(vec, 20.0)
    assert not m["fell"] and 1.2 <= m["mean_speed_mps"] <= 1.4
    assert m["grf_peak_max_bw"] < 2.5 and m["grf_corr"] > 0.85


def test_fbl_ankle_humanlike_walks_20s_more_like_winter():
    """fbl_ankle's human-like preset walks 20 s at 1.2-1.4 m/s with stance GRF peaks under
    fbl_humanlike's 1.8 BW, a vertical GRF correlating 0.9 with Winter's and an ankle
    correlation above fbl_humanlike's 0.64 (experiments/humanlike/README.md)."""
    model, vec, _ = load_preset("fbl_ankle_humanlike")
    assert model == "fbl_ankle"
    m = _walk(vec, 20.0, model=model)
    assert not m["fell"] and 1.2 <= m["mean_speed_mps"] <= 1.4
    assert m["grf_peak_max_bw"] < 1.8 and m["grf_corr"] > 0.9 and m["corr_ankle"] > 0.68


@pytest.mark.slow
def test_fblplus_humanlike_walks_20s_with_low_peaks_and_angles_like_winter():
    """The FBL+ human-like preset walks 20 s near 1.3 m/s with no stance GRF peak above 1.4 BW,
    its vertical GRF and every joint's angle correlating with Winter's, an ankle above
    fbl_ankle_humanlike's 0.79, and a human's energy per metre (about 210 J/m; fbl_walk
    spends 323) (experiments/humanlike/README.md: 60 s figures)."""
    model, vec, _ = load_preset("fblplus_humanlike")
    assert model == "fblplus"
    m = _walk(vec, 20.0, model=model)
    assert not m["fell"] and 1.2 <= m["mean_speed_mps"] <= 1.4
    assert m["grf_peak_max_bw"] < 1.4 and m["grf_corr"] > 0.9
    assert min(m["corr_hip"], m["corr_knee"]) > 0.85 and m["corr_ankle"] > 0.85
    assert m["energy_J_per_m"] < 230.0


@pytest.mark.slow
def test_timestep_convergence(fbl_walk):
    """0.5 ms (the default) vs 0.25 ms: the same 5 s gait measures within 5 %.

    Tolerance: mean speed, mean step length, cycle frequency and energy per metre within
    5 % relative; double-stance fraction within 0.03 absolute.
    """
    a = _walk(fbl_walk, 5.0)
    b = _walk(fbl_walk, 5.0, timestep=0.00025)
    assert not a["fell"] and not b["fell"]
    for k in ("mean_speed_mps", "step_length_mean_m", "cycle_frequency_hz", "energy_J_per_m"):
        assert a[k] == pytest.approx(b[k], rel=0.05), (k, a[k], b[k])
    assert a["double_stance_fraction"] == pytest.approx(b["double_stance_fraction"], abs=0.03)
