"""Loaders of the human reference curves: values, mapping, caching and error messages."""

from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest

from jaxgait.analysis import refdata
from jaxgait.core.resources import data_dir


def read_column(fname, col):
    with (data_dir() / fname).open() as f:
        return np.array([float(r[col]) for r in csv.DictReader(f)])


def test_winter_kinematics_values():
    k = refdata.winter_walking_kinematics()
    assert k.n_samples == 51
    np.testing.assert_array_equal(k.gait_cycle_pct, np.arange(0, 101, 2))
    assert k.hip_mean_deg[0] == pytest.approx(19.33)
    assert k.knee_mean_deg[1] == pytest.approx(7.0)
    assert k.ankle_mean_deg[1] == pytest.approx(-2.06)
    assert k.mean_deg.shape == k.sd_deg.shape == k.sd_is_floor.shape == (51, 3)
    # the missing SD at 100 % is the 0 % SD (periodic cycle); no NaN anywhere
    np.testing.assert_array_equal(k.sd_deg[-1], k.sd_deg[0])
    assert np.all(np.isfinite(k.sd_deg)) and np.all(k.sd_deg > 0)
    # knee: peak flexion in swing, ~60-65 deg near 70-74 %
    i = int(np.argmax(k.knee_mean_deg))
    assert 66 <= k.gait_cycle_pct[i] <= 76 and 55 < k.knee_mean_deg[i] < 70
    assert k.speed_mps == pytest.approx(1.325)


def test_winter_grf_values():
    g = refdata.winter_walking_grf()
    assert g.mean_bw.shape == g.sd_bw.shape == g.ap_mean_bw.shape == (51,)
    i = int(np.argmax(g.mean_bw))
    assert g.mean_bw[i] == pytest.approx(1.103, abs=1e-3) and g.gait_cycle_pct[i] == 14
    assert np.all(g.mean_bw[g.gait_cycle_pct >= 66] == 0)
    assert np.isfinite(g.sd_bw).all() and g.sd_is_floor.dtype == bool


def test_walking_emg_mapping():
    e = refdata.walking_emg()
    assert e.muscles == refdata.EMG_MUSCLES == ("GLU", "HAM", "VAS", "GAS", "SOL", "TA", "RF")
    assert e.envelope.shape == (101, 7)
    f = refdata.WALK_EMG_FILE
    ham = (read_column(f, "medial_hamstrings") + read_column(f, "biceps_femoris")) / 2
    np.testing.assert_allclose(e.curve("HAM"), ham)
    vas = (read_column(f, "vastus_lateralis") + read_column(f, "vastus_medius")) / 2
    np.testing.assert_allclose(e.curve("VAS"), vas)
    np.testing.assert_allclose(e.curve("GLU"), read_column(f, "gluteus_maximus"))
    np.testing.assert_allclose(e.curve("SOL"), read_column(f, "soleus"))
    # physiological timing quoted in SOURCES.md
    assert e.gait_cycle_pct[np.argmax(e.curve("SOL"))] == 51
    assert e.gait_cycle_pct[np.argmax(e.curve("GAS"))] == 45
    # normalised to the trial maximum; the filtered source dips slightly below 0 (TA)
    assert np.all((e.envelope >= -0.05) & (e.envelope <= 1))
    with pytest.raises(KeyError, match="HFL"):
        e.curve("HFL")


def test_running_data():
    k = refdata.running_kinematics()
    assert k.n_samples == 100 and k.gait_cycle_pct[-1] == 99
    f = refdata.RUN_KINEMATICS_FILE
    np.testing.assert_allclose(k.knee_mean_deg, read_column(f, "mean3_knee_flexion_deg"))
    np.testing.assert_allclose(k.hip_sd_deg, read_column(f, "sd3_hip_flexion_deg"))
    assert not k.sd_is_floor.any() and k.speed_mps == 3.5
    g = refdata.running_grf()
    assert g.mean_bw.max() > 2.0  # running impact/active peak well above 1 BW
    e = refdata.running_emg()
    assert e.envelope.shape == (101, 7)
    gas = (
        read_column(refdata.RUN_EMG_FILE, "GASLAT_norm_to_trial_max")
        + read_column(refdata.RUN_EMG_FILE, "GASMED_norm_to_trial_max")
    ) / 2
    np.testing.assert_allclose(e.curve("GAS"), gas)


def test_cached_and_read_only():
    a, b = refdata.winter_walking_kinematics(), refdata.winter_walking_kinematics()
    assert a is b
    assert refdata.winter_walking_kinematics(data_dir()) is a
    with pytest.raises(ValueError):
        a.hip_mean_deg[0] = 0.0
    with pytest.raises(AttributeError):
        a.source = "x"  # frozen


def test_missing_file_names_it(tmp_path):
    with pytest.raises(FileNotFoundError, match=refdata.WINTER_KINEMATICS_FILE):
        refdata.winter_walking_kinematics(tmp_path)


def _copy_with(tmp_path, fname, edit):
    text = (data_dir() / fname).read_text()
    (tmp_path / fname).write_text(edit(text))
    return tmp_path


def test_missing_column_names_file_and_column(tmp_path):
    d = _copy_with(
        tmp_path,
        refdata.WALK_EMG_FILE,
        lambda s: s.replace("biceps_femoris", "biceps_fem", 1),
    )
    with pytest.raises(refdata.RefDataError, match=r"rajagopal2016_walk.*'biceps_femoris'"):
        refdata.walking_emg(d)


def test_bad_number_names_column_and_row(tmp_path):
    def edit(s):
        lines = s.splitlines()
        cells = lines[3].split(",")
        cells[1] = "abc"
        lines[3] = ",".join(cells)
        return "\n".join(lines) + "\n"

    d = _copy_with(tmp_path, refdata.WINTER_KINEMATICS_FILE, edit)
    with pytest.raises(refdata.RefDataError, match=r"'hip_flexion_mean_deg', data row 3"):
        refdata.winter_walking_kinematics(d)


def test_bad_cycle_axis_and_ragged_rows(tmp_path):
    def swap(s):
        lines = s.splitlines()
        lines[2], lines[3] = lines[3], lines[2]
        return "\n".join(lines) + "\n"

    d = _copy_with(tmp_path, refdata.RUN_GRF_FILE, swap)
    with pytest.raises(refdata.RefDataError, match="gait_cycle_pct"):
        refdata.running_grf(d)
    d2 = tmp_path / "ragged"
    d2.mkdir()
    shutil.copy(data_dir() / refdata.RUN_EMG_FILE, d2)
    with (d2 / refdata.RUN_EMG_FILE).open("a") as f:
        f.write("101,0.1\n")
    with pytest.raises(refdata.RefDataError, match="cells"):
        refdata.running_emg(d2)
