"""Videos: frame timing, the stick-figure geometry, and a 1 s video in every backend here."""

from __future__ import annotations

import numpy as np
import pytest

from jaxgait.analysis import video
from jaxgait.analysis.video_mpl import BodyPoses
from jaxgait.world.terrain import flat, slope


def walking_motion(seconds=1.0, model="fbl_planar", terrain=None, dt=0.01):
    """A synthetic motion: the root moves forward at 1.3 m/s, the hips swing, a GRF on the
    right leg grows."""
    t = np.arange(int(round(seconds / dt)) + 1) * dt
    nq = 9 if model == "fbl_planar" else 6
    q = np.zeros((t.size, nq))
    q[:, 0] = 1.3 * t
    q[:, 1] = 0.0 if model == "fbl_planar" else 1.05
    legs = (3, 6) if model == "fbl_planar" else (2, 4)
    q[:, legs[0]] = 0.4 * np.sin(2 * np.pi * t)
    q[:, legs[1]] = -0.4 * np.sin(2 * np.pi * t)
    grf = np.zeros((t.size, 2, 2))
    grf[:, 0, 1] = 800.0 * t
    grf[:, 0, 0] = 50.0
    return video.Motion(t=t, qpos=q, grf=grf, terrain=terrain, model=model, title="synthetic")


def read_frames(path):
    import warnings

    import imageio.v3 as iio

    with warnings.catch_warnings():  # reading an MP4 starts ffmpeg (fork + exec)
        warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
        return np.asarray(iio.imread(path))


def available_backends():
    out = ["matplotlib"]
    if video.mujoco_available()[0]:
        out.append("mujoco")
    return out


@pytest.mark.parametrize("backend", available_backends())
@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_one_second_video(backend, suffix, tmp_path):
    mo = walking_motion(1.0, terrain=slope(0.05, start=1.0))
    info = video.write_video(tmp_path / f"walk{suffix}", mo, backend=backend, fps=10, width=320)
    assert info.backend == backend and info.frames == 10 and info.size == (320, 360)
    frames = read_frames(info.path)
    assert frames.shape == (10, 360, 320, 3)
    diffs = [np.abs(frames[i + 1].astype(int) - frames[i]).mean() for i in range(9)]
    assert min(diffs) > 0.05, diffs  # every frame differs from the previous one
    assert frames.std() > 5.0  # not a blank picture


@pytest.mark.parametrize("backend", available_backends())
def test_taga_body_video(backend, tmp_path):
    mo = walking_motion(0.5, model="taga1991", terrain=flat())
    info = video.write_video(tmp_path / "taga.mp4", mo, backend=backend, fps=8)
    assert info.frames == 4 and read_frames(info.path).shape[0] == 4


def test_frame_rows_timing():
    mo = walking_motion(2.0)
    times, rows = video.frame_rows(mo, 10)
    assert times.size == 20 and rows[0] == 0
    np.testing.assert_allclose(mo.t[rows], times, atol=0.005 + 1e-9)
    times, rows = video.frame_rows(mo, 4, start=1.5, seconds=0.5)
    np.testing.assert_allclose(times, [1.5, 1.75])
    times, _ = video.frame_rows(mo, 30, start=1.9)  # to the end: 0.1 s
    assert times.size == 3
    with pytest.raises(video.VideoError, match="outside"):
        video.frame_rows(mo, 10, start=5.0)
    for bad in (0, -1, 1000, float("nan"), True):
        with pytest.raises(video.VideoError, match="fps"):
            video.frame_rows(mo, bad)


def test_caption_reports_distance_and_speed():
    mo = walking_motion(2.0)
    left, right = video.caption(mo, 100, 1.0)
    assert left == "synthetic" and "t =  1.00 s" in right and "1.30 m" in right
    assert "1.30 m/s" in right


def test_bad_paths_and_backends(tmp_path):
    mo = walking_motion(0.2)
    with pytest.raises(video.VideoError, match=".mp4 or .gif"):
        video.write_video(tmp_path / "walk.avi", mo)
    with pytest.raises(video.VideoError, match="does not exist"):
        video.write_video(tmp_path / "missing" / "walk.mp4", mo)
    with pytest.raises(video.VideoError, match="unknown video backend"):
        video.write_video(tmp_path / "walk.mp4", mo, backend="povray")
    with pytest.raises(video.VideoError, match="frame size"):
        video.write_video(tmp_path / "walk.mp4", mo, width=8)
    with pytest.raises(video.VideoError, match="t \\(T,\\)"):
        video.Motion(t=np.zeros(3), qpos=np.zeros((4, 9)), grf=None, terrain=None)


def test_mujoco_backend_refused_clearly_without_gl(monkeypatch, tmp_path):
    monkeypatch.setenv("MUJOCO_GL", "glfw")  # not an offscreen backend
    ok, why = video.mujoco_available()
    assert not ok and "not an offscreen backend" in why and "libosmesa6" in why
    with pytest.raises(video.VideoError, match="mujoco video backend is not available"):
        video.write_video(tmp_path / "walk.mp4", walking_motion(0.2), backend="mujoco")
    assert video.choose_backend("auto") == "matplotlib"


def test_stick_figure_geometry():
    """The drawn segments are the MJCF geoms placed by MuJoCo's kinematics."""
    body = BodyPoses("fbl_planar")
    seg, cen, feet = body.pose(np.zeros(9))
    hat = body.model.geom("hat").id
    (a, b) = sorted(seg[hat], key=lambda p: p[1])
    np.testing.assert_allclose(a, [0.0, 1.0], atol=1e-9)  # trunk origin (hip) at 1 m
    np.testing.assert_allclose(b, [0.0, 1.8], atol=1e-9)  # HAT capsule 0.8 m long
    np.testing.assert_allclose(feet, [[0.06, 0.0], [0.06, 0.0]], atol=1e-9)  # heel/ball mid
    assert sorted(set(body.sides)) == ["", "l", "r"]
    assert body.sides.index("r") > body.sides.index("l")  # right leg drawn in front
    taga = BodyPoses("taga1991")
    _, cen, feet = taga.pose(np.array([0.0, 1.1, 0.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(feet, [[0.0, 0.0], [0.0, 0.0]], atol=1e-9)  # ankles, legs down
    assert len(cen) == 1  # the hip point mass
