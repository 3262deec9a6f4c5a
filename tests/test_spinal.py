"""The spinal network (thesis 6.1-6.2): IN_SEN against hand-computed values, the network
reorganisation against FBL, IN_BAS and IN_CPG outputs, the control vector, network presets."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, presets, sim
from jaxgait.control import fbl
from jaxgait.control import interneurons as ins
from jaxgait.control.commands import schedule
from jaxgait.control.network_json import network_from_dict, network_to_dict
from jaxgait.control.spinal import FBL_NET, Network, NetworkError, spinal_controller
from jaxgait.spinal.record import record
from jaxgait.world import envs

P = fbl.FBL.unpack(jnp.asarray(fbl.FBL.init, jnp.float32))
K = ins.index


def _sensors(rng, rows):
    s = rng.uniform(0.0, 1.5, (rows, fbl.N_SENSORS)).astype(np.float32)
    stance = rng.random(rows) < 0.5
    s[:, fbl.S_STANCE] = stance
    s[:, fbl.S_DS] = stance & (rng.random(rows) < 0.5)
    s[:, fbl.S_TRUNK] = rng.normal(0.1, 0.2, rows)
    s[:, fbl.S_DTRUNK] = rng.normal(0, 1.0, rows)
    s[:, fbl.S_KNEE] = rng.uniform(2.6, 3.3, rows)
    s[:, fbl.S_DKNEE] = rng.normal(0, 2.0, rows)
    s[:, fbl.S_THETA_TO] = rng.normal(0.1, 0.1, rows)
    return jnp.asarray(s)


def test_interneurons_by_hand():
    s = np.zeros((1, fbl.N_SENSORS), np.float32)
    s[0, fbl.S_F] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]  # HFL GLU HAM VAS GAS SOL TA
    s[0, fbl.S_L] = [0.9, 1.0, 1.1, 1.0, 1.0, 1.0, 0.8]
    s[0, fbl.S_LOAD], s[0, fbl.S_LOAD_C] = 0.8, 0.3
    s[0, fbl.S_STANCE], s[0, fbl.S_DS] = 1.0, 1.0
    s[0, fbl.S_TRUNK], s[0, fbl.S_DTRUNK] = 0.2, 0.5
    s[0, fbl.S_KNEE], s[0, fbl.S_DKNEE] = 3.0, 1.0
    s[0, fbl.S_THETA_TO] = 0.15
    x, gate = ins.insen_inputs(P, jnp.asarray(s))
    x, gate = np.asarray(x[0]), np.asarray(gate[0])
    p = {k: float(v) for k, v in P.items()}
    u1 = p["k_p1"] * (0.2 - p["theta_ref"]) + p["k_d"] * 0.5
    u2 = p["k_p2"] * (0.2 - p["theta_ref"]) + p["k_d"] * 0.5
    want = {
        "SOL<-SOL MFF ST": p["G_SOL"] * 0.6,
        "TA<-TA MLF CY": p["G_TA"] * (0.8 - p["loff_TA"]),
        "TA<-SOL MFF ST": p["G_TA_SOL"] * 0.6,
        "GAS<-GAS MFF ST": p["G_GAS"] * 0.5,
        "VAS<-VAS MFF ST": p["G_VAS"] * 0.4,
        "VAS<-GCF STend": p["k_bw"] * 0.3,
        "HAM<-GIF ST": max(u1, 0) * p["k_bw"] * 0.8,
        "GLU<-GIF ST": max(u2, 0) * p["k_bw"] * 0.8,
        "HF<-GIF ST": max(-u1, 0) * p["k_bw"] * 0.8,
        "HAM<-HAM MFF SW": p["G_HAM"] * 0.3,
        "GLU<-GLU MFF SW": p["G_GLU"] * 0.2,
        "HF<-HF MLF SW": p["G_HFL"] * max(0.9 - p["loff_HFL"], 0),
        "HF<-HAM MLF SW": p["G_HAM_HFL"] * max(1.1 - p["loff_HAM"], 0),
        "HF<-TL SW": p["k_lean"] * (0.15 - p["theta_ref"]),
        "VAS<-KNEE OPF ST": p["k_phi"] * (3.0 - p["phi_k_off"]),
    }
    for name, v in want.items():
        assert x[K(name)] == pytest.approx(v, rel=1e-5, abs=1e-7), name
    on = {i.name for i in ins.IN_SEN if i.gate in ("stance", "cycle", "stance_end")}
    assert {n for n in ins.IN_NAMES if gate[K(n)] == 1} == on


@pytest.mark.parametrize("seed", range(4))
def test_motoneurons_sum_to_fbl_law(seed):
    s = _sensors(np.random.default_rng(seed), 64)
    x, gate = ins.insen_inputs(P, s)
    stim = ins.motoneurons(ins.direct_terms(P, s), x * gate)
    np.testing.assert_allclose(np.asarray(stim), np.asarray(fbl.fbl_stimulation(P, s)), atol=2e-6)


@pytest.mark.parametrize("seed", range(2))
def test_reorganised_fblplus_law_is_fblplus(seed):
    # FBL+'s stance end by CoM distance and its swing-end PD rules, on the network's
    # per-delay-group inputs (3 groups x 2 legs), summed at the motoneurons: FBL+'s law
    from jaxgait.control import fblplus
    from jaxgait.control.spinal import _delayed_inputs

    rng = np.random.default_rng(seed)
    s = np.array(_sensors(rng, 6))
    # rows are (group, leg): the right leg in stance with the CoM past d_st_end (stance end
    # without double support), the left in swing with its foot ahead of d_sw_end (swing end)
    s[:, fbl.S_STANCE], s[:, fbl.S_DS] = np.tile([1.0, 0.0], 3), 0.0
    s[:, fbl.S_DCOM] = np.tile([1.0, -1.0], 3) + rng.uniform(-0.3, 0.3, 6)
    s[:, fbl.S_HIP] = rng.uniform(2.5, 3.6, 6)
    s[:, fbl.S_DHIP] = rng.normal(0, 2.0, 6)
    vals = dict(zip(fblplus.FBLPLUS.names, map(float, fblplus.FBLPLUS.init), strict=True))
    vals.update(kp_HFL=1.2, kd_HFL=0.3, kp_GLU=0.8, kd_GLU=0.2, kp_VAS=1.5, kd_VAS=0.4)
    vals.update(d_st_end=0.5, d_sw_end=-0.4)
    p = {k: jnp.float32(v) for k, v in vals.items()}
    s = jnp.asarray(s)
    r, gate, direct = _delayed_inputs(p, s.reshape(3, 2, -1), plus=True)
    stim = np.asarray(ins.motoneurons(direct, r * gate))
    law = np.asarray(fblplus.fblplus_stimulation(p, s)).reshape(3, 2, -1)
    want = np.stack([law[fbl.MUSCLE_DELAY_GROUP[m], :, m] for m in range(fbl.N_MUSCLES)], -1)
    np.testing.assert_allclose(stim, want, atol=3e-6)
    # the rules are live on these inputs: without them the network is FBL's, not FBL+'s
    r0, g0, d0 = _delayed_inputs(p, s.reshape(3, 2, -1))
    assert np.abs(np.asarray(ins.motoneurons(d0, r0 * g0)) - want).max() > 1e-2


def _vec():
    _, vec, _ = presets.load_preset("fbl_walk")
    return jnp.asarray(vec, jnp.float32)


_ROLLOUTS = {}


def _roll(model, commands=None):
    """A 1.2 s rollout of fbl_walk on flat ground (one compiled function per model)."""
    if id(model) not in _ROLLOUTS:
        cfg = sim.SimConfig(duration=1.2)
        _ROLLOUTS[id(model)] = (model, sim.make_rollout(model, cfg, batched=False))
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    return _ROLLOUTS[id(model)][1](_vec(), env, commands)


def test_reorganised_fbl_walks_like_fbl():
    tr_f, _, sm_f, _ = _roll(models.get_model("fbl"))
    tr_n, _, sm_n, _ = _roll(models.get_model("fbl_net"))
    # the same law summed in another order: float32 rounding only, over 1.2 s of walking
    np.testing.assert_allclose(np.asarray(tr_n.stim), np.asarray(tr_f.stim), atol=2e-3)
    np.testing.assert_allclose(np.asarray(tr_n.qpos), np.asarray(tr_f.qpos), atol=2e-3)
    assert not bool(sm_n.fell)


def test_groups_alone_change_nothing_and_fast_links_pass_through():
    # every IN_SEN kept (FBL- with nothing replaced), spread over the three control groups,
    # with links 5x faster than the time step: FBL reorganised within 1e-2 (a jump of the
    # input lags by e^(-dt/tau) = 0.7 % of its size for one step), 1e-4 on average
    from jaxgait.sim.model import planar_model

    groups = tuple(("sen", "cpg", "bas")[k % 3] for k in range(ins.N_IN))
    net = Network(name="t_groups", groups=groups, tau_in=1e-4, tau_mn=1e-4)
    a = _roll(planar_model(spinal_controller(net)))[0]
    b = _roll(models.get_model("fbl_net"))[0]
    diff = np.abs(np.asarray(a.stim) - np.asarray(b.stim))
    assert 0 < diff.max() < 1e-2 and diff.mean() < 1e-4


def test_a_changed_control_vector_acts_only_after_the_change():
    model = models.get_model("fbl_net")
    sched = schedule(model.controller.commands, [(0.0, {}), (0.6, {"A_INSEN": 0.7})])
    base = _roll(model)[0]
    changed = _roll(model, sched)[0]
    t = np.asarray(base.t)
    before, after = t < 0.6 - 1e-6, t > 0.65
    np.testing.assert_array_equal(np.asarray(base.stim)[before], np.asarray(changed.stim)[before])
    assert np.abs(np.asarray(base.stim)[after] - np.asarray(changed.stim)[after]).max() > 0.01
    # the trunk-lean command is an offset of theta_ref: from t = 0 it is the same rollout as
    # the parameter moved by as much
    lean = schedule(model.controller.commands, [(0.0, {"lean_offset": 0.03})])
    by_command = _roll(model, lean)[0]
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    vec = _vec().at[fbl.FBL.names.index("theta_ref")].add(0.03)
    by_param = _ROLLOUTS[id(model)][1](vec, env, None)[0]
    np.testing.assert_allclose(np.asarray(by_command.qpos), np.asarray(by_param.qpos), atol=1e-5)
    assert np.abs(np.asarray(by_command.qpos) - np.asarray(base.qpos)).max() > 1e-3


def _feedforward_doc(tmp_path, ff_after=0):
    kb, kc = K("TA<-SOL MFF ST"), K("GLU<-GLU MFF SW")
    kinds = ["sen"] * ins.N_IN
    kinds[kb], kinds[kc] = "bas", "cpg"
    ph = np.arange(100) / 100
    pat = np.sin(2 * np.pi * ph) / np.std(np.sin(2 * np.pi * ph))
    net = Network(
        name="t_feedforward",
        kinds=tuple(kinds),
        groups=tuple("cpg" if k == "cpg" else k for k in kinds),
        bas_level=tuple(0.123 if k == kb else 0.0 for k in range(ins.N_IN)),
        cpg_mean=tuple(0.2 if k == kc else 0.0 for k in range(ins.N_IN)),
        cpg_sd=tuple(0.05 if k == kc else 0.0 for k in range(ins.N_IN)),
        cpg_pattern=np.broadcast_to(pat, (2, ins.N_IN, 100)).copy(),
        omega=1.0,
        ff_after=ff_after,
    )
    doc = {
        "model": net.name,
        "table": "fbl",
        "params": dict(zip(fbl.FBL.names, map(float, np.asarray(_vec())), strict=False)),
        "network": network_to_dict(net),
    }
    path = tmp_path / "net.json"
    path.write_text(json.dumps(doc))
    return path, kb, kc


def test_basal_and_cpg_interneuron_outputs(tmp_path):
    path, kb, kc = _feedforward_doc(tmp_path)
    try:
        rec = record(path, duration=1.0)
        gate = rec.gate[:, :, kb]
        np.testing.assert_allclose(rec.out[:, :, kb], 0.123 * gate, rtol=1e-6)
        assert set(np.unique(gate)) == {0.0, 1.0}
        cpg_out = rec.out[rec.t > 0.1, :, kc]  # mu + sd g(theta), whatever the gate
        assert cpg_out.min() >= 0.2 - 0.05 * np.sqrt(2) * 1.02
        assert cpg_out.max() <= 0.2 + 0.05 * np.sqrt(2) * 1.02
        assert cpg_out.max() - cpg_out.min() > 0.05
    finally:
        presets.forget_network("t_feedforward")


def test_feedforward_waits_for_its_touchdown(tmp_path):
    path, kb, _ = _feedforward_doc(tmp_path, ff_after=1)
    try:
        rec = record(path, duration=1.5)
        first = np.flatnonzero(rec.stance[1:, 0] & ~rec.stance[:-1, 0])[0] + 1
        sensory = rec.out[:first, 0, kb]
        assert np.all(np.abs(sensory - 0.123) > 1e-6) and np.any(sensory > 0)
        on = rec.out[first + 1 :, 0, kb]
        np.testing.assert_allclose(on, 0.123 * rec.gate[first + 1 :, 0, kb], rtol=1e-6)
    finally:
        presets.forget_network("t_feedforward")


def test_network_json_round_trip_and_errors(tmp_path):
    path, kb, kc = _feedforward_doc(tmp_path)
    doc = json.loads(path.read_text())
    net = network_from_dict(doc["network"], "t_rt")
    again = network_to_dict(net)
    assert again == doc["network"]
    assert net.members("bas") == (ins.IN_NAMES[kb],) and net.members("cpg") == (ins.IN_NAMES[kc],)
    bad = json.loads(path.read_text())
    bad["network"]["kinds"]["NOPE<-X"] = "bas"
    with pytest.raises(presets.PresetError, match=r"net.json.*unknown IN_SEN"):
        presets.preset_from_dict(bad, where=str(path))
    bad = json.loads(path.read_text())
    bad["network"]["kinds"]["SOL<-SOL MFF ST"] = "cpg"  # a CPG without a pattern
    with pytest.raises(presets.PresetError, match="need finite patterns"):
        presets.preset_from_dict(bad, where="x.json")
    bad = json.loads(path.read_text())
    bad["model"] = "fbl"
    with pytest.raises(presets.PresetError, match="built-in model"):
        presets.preset_from_dict(bad, where="x.json")
    with pytest.raises(NetworkError, match="kinds"):
        Network(name="x", kinds=("sen",) * 3)
    assert "fbl_net" in models.model_names() and FBL_NET.members("bas") == ()
    # a network on FBL+ keeps its base through JSON (written only when not FBL's) and
    # drives FBL+'s table; a preset giving it FBL's table is refused
    plus = network_from_dict(dict(doc["network"], base="fblplus"), "t_rt_plus")
    assert plus.base == "fblplus" and network_to_dict(plus)["base"] == "fblplus"
    assert "base" not in again and spinal_controller(plus).table.name == "fblplus"
    assert models.get_model("fblplus_net").table.name == "fblplus"
    bad = dict(json.loads(path.read_text()), model="t_rt_plus2")
    bad["network"]["base"] = "fblplus"
    with pytest.raises(presets.PresetError, match="drives the table 'fblplus'"):
        presets.preset_from_dict(bad, where="x.json")
    with pytest.raises(NetworkError, match="base 'wang'"):
        Network(name="x", base="wang")


# ------------------------------------------------------------------- building models


def _analysis(s_of):
    from jaxgait.analysis.variability import Variability
    from jaxgait.spinal.record import Analysis

    per_leg = {}
    for k, n in enumerate(ins.IN_NAMES):
        v = Variability(
            s=s_of(n, k),
            v_mu=0.01,
            v_sigma=0.02,
            mu=np.full(5, 0.1 * k),
            sigma=np.full(5, 0.02),
            pattern=np.sin(2 * np.pi * np.arange(100) / 100) * np.sqrt(2),
            durations=np.full(5, 1.1),
            mean_active=0.2 * k,
        )
        per_leg[n] = (v, v)
    return Analysis(per_leg=per_leg, stride_s=1.25, first_td=(0.2, 0.7), n_cycles=(5, 5))


def test_selection_takes_the_least_variable_candidates():
    from jaxgait.spinal.build import select
    from jaxgait.spinal.record import SpinalError

    an = _analysis(lambda n, k: 0.5 - 0.03 * k)  # later IN in the table: less variable
    muscle = [i.name for i in ins.IN_SEN if i.muscle_feedback]
    got = select(an, 5)
    assert got == sorted(muscle, key=lambda n: an.factor(n, "s"))[:5]
    assert all(n in muscle for n in got)
    assert "VAS<-KNEE OPF ST" not in select(an, 13, candidates="replaceable")
    assert len(select(an, 13, candidates="replaceable")) == 13  # the thesis's 13 per leg
    assert all(an.factor(n, "s") < 0.2 for n in select(an, None, s_max=0.2))
    with pytest.raises(SpinalError, match="n_replace"):
        select(an, 10)
    with pytest.raises(SpinalError, match="candidates"):
        select(an, 2, candidates="all")


@pytest.mark.parametrize("kind", ["fbl_net", "fblminus", "3fbl", "3fbl_prime"])
def test_build_network_kinds_and_groups(kind):
    from jaxgait.spinal.build import build_network

    an = _analysis(lambda n, k: 0.01)
    rep = ["GLU<-GLU MFF SW", "HF<-HF MLF SW", "SOL<-SOL MFF ST", "GAS<-GAS MFF ST"]
    net = build_network(kind, an, rep, f"t_{kind}", omega=None)
    hip, other = rep[:2], rep[2:]
    g = dict(zip(ins.IN_NAMES, net.groups, strict=True))
    kd = dict(zip(ins.IN_NAMES, net.kinds, strict=True))
    assert all(g[n] == "sen" and kd[n] == "sen" for n in ins.IN_NAMES if n not in rep)
    assert all(g[n] == "bas" for n in other)
    assert all(g[n] == ("bas" if kind == "fblminus" else "cpg") for n in hip)
    want = {
        "fbl_net": ("sen", "sen"),
        "fblminus": ("bas", "bas"),
        "3fbl": ("cpg", "bas"),
        "3fbl_prime": ("cpg", "sen"),
    }[kind]
    assert all(kd[n] == want[0] for n in hip) and all(kd[n] == want[1] for n in other)
    k = ins.index("SOL<-SOL MFF ST")
    assert net.bas_level[k] == pytest.approx(0.2 * k)  # mean over the active phase
    assert net.omega == pytest.approx(0.8)  # the gait's stride frequency (1 / 1.25 s)
    assert build_network(kind, an, rep, "t_default").omega == 0.85  # eq. 6.3
    assert net.theta0 == pytest.approx((1 - 0.8 * 0.2, 1 - 0.8 * 0.7))
    cmds = [c.name for c in spinal_controller(net).commands]
    assert cmds[:2] == ["A_INSEN", "O_INSEN"]
    assert ("omega" in cmds) == (kind in ("3fbl", "3fbl_prime"))
    assert ("A_INCPG" in cmds) == (kind != "fblminus")
    assert cmds[-1] == "lean_offset"  # the trunk-lean command, beyond the thesis's C


def test_spinal_cli_errors_are_clear(capsys):
    from jaxgait.spinal.cli import main

    assert main(["variability", "no_such_preset"]) == 2
    assert "no_such_preset" in capsys.readouterr().err
    assert main(["build", "fbl_walk", "--kinds", "fbl,nope"]) == 2
    assert "--kinds" in capsys.readouterr().err


@pytest.mark.slow
def test_reorganised_fblplus_walks_like_fblplus():
    # exp5's fast walk, whose FBL+ rules are active, on FBL+ and on its network
    _, vec, doc = presets.load_preset("fblplus_fastwalk")
    cfg = sim.SimConfig(duration=1.2, v0=doc["v0"])
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    runs = [
        sim.make_rollout(models.get_model(m), cfg, batched=False)(jnp.asarray(vec), env)
        for m in ("fblplus", "fblplus_net")
    ]
    (tr_p, _, _, _), (tr_n, _, sm_n, _) = runs
    # float rounding of the sums only; at 2.4 m/s it grows to a few 1e-3 by the end
    first = np.asarray(tr_p.t) <= 1.0
    for a, b in ((tr_n.stim, tr_p.stim), (tr_n.qpos, tr_p.qpos)):
        np.testing.assert_allclose(np.asarray(a)[first], np.asarray(b)[first], atol=2e-3)
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), atol=1e-2)
    assert not bool(sm_n.fell)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name", ["fblminus_walk", "3fbl_walk", "3fbl_prime_walk", "plus_3fbl_walk"]
)
def test_shipped_spinal_models_walk(name):
    from jaxgait import evaluate

    rep = evaluate.run(name, duration=20.0).report
    assert not rep["fell"] and rep["distance_m"] > 20.0
    table = "fblplus" if name.startswith("plus_") else "fbl"  # built from an FBL+ gait
    assert rep["model"] == name and models.get_spec(name).table.name == table


@pytest.mark.slow
def test_train_accepts_a_network_model(tmp_path):
    from jaxgait.train import cli

    out = tmp_path / "run"
    args = ["quickstart", "--set", 'model="3fbl_walk"', "--set", 'init="3fbl_walk"']
    args += ["--iterations", "1", "--particles", "2", "--duration", "1", "--out", str(out)]
    assert cli.main(args + ["--no-plots"]) == 0
    doc = json.loads((out / "best.json").read_text())
    assert doc["model"] == "3fbl_walk" and doc["network"]["kinds"]["GLU<-GLU MFF SW"] == "cpg"
    name, vec, _ = presets.load_preset(out)
    assert name == "3fbl_walk" and vec.shape == (fbl.FBL.size,)
