"""render_frames with a fake backend (no engine): frames, manifest, resume, video, callbacks, reuse."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

import blendify_core as bf
from blendify_core.utils import Trajectory, render_frames
from blendify_core.utils.animation import MANIFEST_NAME, write_video


def _traj():
    t = Trajectory()
    t.add_keypoint((0, -3, 1), (0, 0, 0), 0.0, rotation_mode="look_at")
    t.add_keypoint((3, 0, 1), (0, 0, 0), 0.4, rotation_mode="look_at")
    return t


def _png(path):
    with Image.open(path) as im:
        return np.asarray(im)


def test_trajectory_frames_follow_the_camera_and_camera_is_restored(fake_backend, small_scene, tmp_path):
    cam = small_scene.camera
    before = (cam.translation.copy(), cam.quaternion.copy())
    rep = render_frames(small_scene, _traj(), backend=fake_backend.name, frames_dir=tmp_path, fps=10, progress=False)
    assert len(rep) == 5 and rep.rendered == [0, 1, 2, 3, 4] and rep.skipped == []
    assert [p.name for p in rep.frames] == [f"frame_{i:05d}.png" for i in range(5)]
    first, last = _png(rep.frames[0]), _png(rep.frames[-1])
    assert first.shape == (16, 24, 4)
    assert first[5, 0, 3] == 0 and first[5, 5, 3] == 255  # transparent column kept in the PNG
    # the fake colour encodes the camera x position: 0 at the start, 3 at the end
    assert last[5, 5, 0] > first[5, 5, 0] + 40
    np.testing.assert_array_equal(cam.translation, before[0])
    np.testing.assert_array_equal(cam.quaternion, before[1])
    assert len(fake_backend.instances) == 1 and fake_backend.instances[0].renders == 5  # one instance reused
    lines = [json.loads(line) for line in (tmp_path / MANIFEST_NAME).read_text().splitlines()]
    assert [e["frame"] for e in lines] == [f"{i:05d}" for i in range(5)]
    assert lines[0]["settings"]["backend"] == fake_backend.name
    assert len(lines[0]["fingerprint"]) == 64


def test_resume_skips_finished_frames_and_rerenders_changed_ones(fake_backend, small_scene, tmp_path):
    kw = dict(backend=fake_backend.name, frames_dir=tmp_path, fps=10, progress=False)
    calls = []

    def interrupt_at_3(scene, i):
        calls.append(i)
        if i == 3:
            raise KeyboardInterrupt

    # an interrupted run (a callback that raises mid-way): frames 0-2 are finished
    with pytest.raises(KeyboardInterrupt):
        render_frames(small_scene, interrupt_at_3, n_frames=5, **kw)
    assert sorted(p.name for p in tmp_path.glob("frame_*.png")) == [f"frame_{i:05d}.png" for i in range(3)]
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind

    def nothing(scene, i):
        calls.append(i)

    rep = render_frames(small_scene, nothing, n_frames=5, **kw)
    assert rep.skipped == [0, 1, 2] and rep.rendered == [3, 4]
    # a deleted PNG and a changed setting are re-rendered
    (tmp_path / "frame_00001.png").unlink()
    rep = render_frames(small_scene, nothing, n_frames=5, **kw)
    assert rep.rendered == [1]
    rep = render_frames(small_scene, nothing, n_frames=5, seed=7, **kw)
    assert rep.rendered == [0, 1, 2, 3, 4]
    # a changed scene (the callback moves the cube in frames >= 3) re-renders only those frames
    cube = next(iter(small_scene.renderables))

    def move_late(scene, i):
        cube.set_position(translation=(0, 0, 0.5 if i >= 3 else 0.0))

    rep = render_frames(small_scene, move_late, n_frames=5, seed=7, **kw)
    assert rep.rendered == [3, 4]
    rep = render_frames(small_scene, move_late, n_frames=5, seed=7, resume=False, **kw)
    assert rep.rendered == [0, 1, 2, 3, 4]
    # the manifest stays compact (one line per frame after a rewrite) and tolerates a torn last line
    with open(tmp_path / MANIFEST_NAME, "a") as f:
        f.write('{"version": 1, "frame": "00002", "fingerp')
    rep = render_frames(small_scene, move_late, n_frames=5, seed=7, **kw)
    assert rep.skipped == [0, 1, 2, 3, 4]
    assert len((tmp_path / MANIFEST_NAME).read_text().splitlines()) == 5


def test_callback_updates_any_object_and_results_are_returned(fake_backend, small_scene):
    def move_camera(scene, i):
        scene.camera.set_position(translation=(float(i), -3.0, 1.0))

    rep = render_frames(small_scene, move_camera, backend=fake_backend.name, n_frames=3, progress=False)
    assert len(rep.results) == 3 and rep.frames == [] and rep.video is None
    reds = [float(r.rgba[5, 5, 0]) for r in rep.results]
    np.testing.assert_allclose(reds, [0.5, 0.6, 0.7], atol=1e-6)


def test_extra_outputs_are_saved(fake_backend, small_scene, tmp_path):
    rep = render_frames(
        small_scene,
        _traj(),
        backend=fake_backend.name,
        frames_dir=tmp_path,
        fps=5,
        progress=True,
        outputs=("rgb", "depth"),
    )
    assert len(rep) == 3
    assert sorted(p.name for p in tmp_path.glob("depth_*.png")) == [
        "depth_00000.png",
        "depth_00001.png",
        "depth_00002.png",
    ]


def test_video_is_written_and_resumed(fake_backend, small_scene, tmp_path):
    pytest.importorskip("imageio", reason="the 'video' extra (imageio) is not installed")
    pytest.importorskip("imageio_ffmpeg", reason="the 'video' extra (imageio-ffmpeg) is not installed")
    import imageio.v2 as imageio

    video = tmp_path / "orbit.mp4"
    small_scene.camera.set_position(translation=(0, -3, 1))
    kw = dict(backend=fake_backend.name, frames_dir=tmp_path / "frames", video_path=video, fps=10, progress=False)
    rep = render_frames(small_scene, _traj(), **kw)
    assert rep.video == video and video.stat().st_size > 0
    with imageio.get_reader(str(video)) as reader:
        frames = [f for f in reader]
    assert len(frames) == 5 and frames[0].shape == (16, 24, 3)
    assert frames[-1][8, 12, 0] > frames[0][8, 12, 0] + 30  # the colour follows the camera
    assert frames[0][8, 0].min() > 200  # transparent column over the white background
    # resume: nothing re-rendered, video rebuilt from the PNGs
    video.unlink()
    rep = render_frames(small_scene, _traj(), **kw)
    assert rep.rendered == [] and video.is_file()
    # a video alone (no frames_dir) also works, and odd sizes are padded to even
    odd = write_video([np.zeros((7, 9, 3), np.uint8)] * 2, tmp_path / "odd.mp4", fps=5)
    with imageio.get_reader(str(odd)) as reader:
        assert next(iter(reader)).shape == (8, 10, 3)


def test_bad_arguments(fake_backend, small_scene, tmp_path):
    with pytest.raises(bf.InvalidSceneError, match="n_frames"):
        render_frames(small_scene, lambda s, i: None, backend=fake_backend.name)
    with pytest.raises(bf.InvalidSceneError, match="trajectory_or_callback"):
        render_frames(small_scene, 42, backend=fake_backend.name)
    with pytest.raises(bf.InvalidSceneError, match="scene"):
        render_frames("scene", _traj(), backend=fake_backend.name)
    with pytest.raises(bf.InvalidSceneError, match="fps"):
        render_frames(small_scene, _traj(), backend=fake_backend.name, fps=0)
    with pytest.raises(bf.InvalidSceneError, match="video_path"):
        render_frames(
            small_scene, _traj(), backend=fake_backend.name, video_path=tmp_path / "v.mp4", outputs=("depth",)
        )
    with pytest.raises(bf.InvalidSceneError, match="video_path"):
        render_frames(small_scene, _traj(), backend=fake_backend.name, video_path=tmp_path / "missing" / "v.mp4")


def test_bf_render_frames_is_exported():
    assert bf.render_frames is render_frames


def test_real_backend_two_frames(tmp_path):
    """Two tiny frames through a real engine when one is available here."""
    status = bf.available_backends()
    name = next((n for n in ("pyrender", "cycles", "mitsuba") if n in status and status[n].available), None)
    if name is None:
        reasons = {n: s.reason for n, s in status.items()}
        print(f"skipping: no real backend is available ({reasons})")
        pytest.skip(f"no real backend is available: {reasons}")
    scene = bf.Scene()
    scene.set_perspective_camera(
        (32, 24), fov_x=0.8, rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, -4, 1)
    )
    scene.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.3, 0.2)))
    scene.lights.add_sun(strength=3.0, rotation_mode="eulerXYZ", rotation=(30, 0, 20))
    t = Trajectory()
    t.add_keypoint((0, -4, 1), (0, 0, 0), 0.0, rotation_mode="look_at")
    t.add_keypoint((4, 0, 1), (0, 0, 0), 1.0, rotation_mode="look_at")
    rep = render_frames(
        scene, t, backend=name, quality="preview", samples=4, frames_dir=tmp_path, fps=1, progress=False
    )
    assert rep.rendered == [0, 1]
    a, b = _png(rep.frames[0]), _png(rep.frames[1])
    assert a[..., 3].max() == 255 and b[..., 3].max() == 255  # the cube is visible in both
    rep = render_frames(
        scene, t, backend=name, quality="preview", samples=4, frames_dir=tmp_path, fps=1, progress=False
    )
    assert rep.skipped == [0, 1]


def test_on_frame_recolours_a_point_cloud_for_each_camera(fake_backend, tmp_path):
    from blendify_core.utils import approximate_colors_from_camera

    scene = bf.Scene()
    scene.set_perspective_camera((16, 16), fov_x=0.8, translation=(0, -3, 0))
    pts = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    normals = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    pc = scene.renderables.add_pointcloud(pts, bf.DiffuseMaterial(), bf.VertexColors(np.ones((2, 3))))
    scene.lights.add_sun(strength=1.0)
    seen = []

    def recolour(s, i):
        cols = approximate_colors_from_camera(s.camera, normals, np.ones((2, 3)), (0, 0, 0, 0), points=pts)
        pc.update_colors(bf.VertexColors(cols))
        seen.append(cols[:, 3].tolist())

    t = Trajectory()
    t.add_keypoint((0, -3, 0), (0, 0, 0), 0.0, rotation_mode="look_at")
    t.add_keypoint((0, 3, 0), (0, 0, 0), 1.0, rotation_mode="look_at")
    rep = render_frames(scene, [t[0], t[1]], backend=fake_backend.name, on_frame=recolour, progress=False)
    assert len(rep.results) == 2
    assert seen == [[1.0, 0.0], [0.0, 1.0]]  # the point facing each camera stays visible
    with pytest.raises(bf.InvalidSceneError, match="on_frame"):
        render_frames(scene, t, backend=fake_backend.name, on_frame=3)
