"""Files the library writes for the user get the mode a plain ``open(path, "w")`` would give them
(0o666 & ~umask for a new file, the old permission bits when overwriting) without the process umask ever
being changed, and a file that cannot be written raises OutputError (also an OSError) naming the path,
leaving nothing behind."""

from __future__ import annotations

import errno
import importlib.util
import os
import pickle
import stat
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.errors import MissingFolderError, OutputError
from blendify_core.io.output import AtomicOutput, atomic_write, ensure_folder
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import depth_plane_scene


class _FlatBackend(Backend):
    """A flat grey picture with a plane's exact depth (no engine); ``gain`` tells two of them apart."""

    gain = 1.0

    @classmethod
    def capabilities(cls):
        caps = {k: Capability("exact") for k in ALL_FEATURES}
        caps["output.albedo"] = Capability("unsupported", "no albedo")
        return caps

    def translate(self, scene, settings):
        return scene

    def render(self, native, settings):
        from blendify_core.testing import expected_plane_depth

        d = expected_plane_depth(native).astype(np.float32)
        rgba = np.zeros(d.shape + (4,), np.float32)
        rgba[np.isfinite(d)] = (0.25 * self.gain, 0.25 * self.gain, 0.25 * self.gain, 1.0)
        return bf.RenderResult(rgba=rgba, depth=d if settings.wants("depth") else None, meta={})


class FlatA(_FlatBackend):
    name = "modes-flat-a"


class FlatB(_FlatBackend):
    name = "modes-flat-b"
    gain = 1.01


@pytest.fixture
def flat_backends():
    register_backend(FlatA.name, FlatA)
    register_backend(FlatB.name, FlatB)
    yield
    unregister_backend(FlatA.name)
    unregister_backend(FlatB.name)
    bf.close_backends()


@pytest.fixture(params=[0o022, 0o077], ids=["umask022", "umask077"])
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _result() -> bf.RenderResult:
    rgba = np.zeros((6, 8, 4), np.float32)
    rgba[..., 3] = 1.0
    return bf.RenderResult(rgba=rgba, depth=np.full((6, 8), 2.0, np.float32), meta={"backend": "test"})


def _scene() -> bf.Scene:
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    scene.set_perspective_camera((16, 12), fov_x=0.7, translation=(0, 0, 4))
    return scene


def _mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def _video(path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg", reason="the MP4 writer needs the 'video' extra (imageio-ffmpeg)")
    from blendify_core.utils import write_video

    write_video([np.zeros((8, 8, 3), np.uint8)] * 2, path, fps=5)


def _exr(path: Path) -> None:
    pytest.importorskip("OpenEXR", reason="writing .exr needs the 'openexr' package")
    _result().save(path, output="depth")


def _text(path: Path) -> None:
    def write(tmp: str) -> None:
        with open(tmp, "w") as f:
            f.write("ok")

    atomic_write(path, write)


#: writers of one file: name -> (file name, call(path))
FILE_WRITERS = {
    "result-png": ("x.png", lambda p: _result().save(p)),
    "result-depth-png": ("x.png", lambda p: _result().save(p, output="depth")),
    "result-npz": ("x.npz", lambda p: _result().save(p)),
    "result-exr": ("x.exr", _exr),
    "scene-npz": ("s.npz", lambda p: _scene().save(p)),
    "video-mp4": ("v.mp4", _video),
    "atomic_write": ("m.json", _text),  # what the demo and the batch manifest use
}


def _render_frames(folder: Path) -> None:
    pytest.importorskip("imageio_ffmpeg", reason="the MP4 writer needs the 'video' extra (imageio-ffmpeg)")
    from blendify_core.utils import render_frames

    render_frames(
        depth_plane_scene(),
        lambda scene, i: None,
        n_frames=2,
        backend=FlatA.name,
        frames_dir=folder / "frames",
        video_path=folder / "v.mp4",
        progress=False,
        outputs=("rgb", "depth"),
        samples=1,
    )


def _compare_report(folder: Path) -> None:
    scene = depth_plane_scene()
    a = bf.render(scene, backend=FlatA.name, samples=1, outputs=("rgb", "depth"))
    b = bf.render(scene, backend=FlatB.name, samples=1, outputs=("rgb", "depth"))
    bf.compare(a, b, tier="pathtracer").save(folder / "report")


def _crosscheck_report(folder: Path) -> None:
    rep = bf.crosscheck(depth_plane_scene(), backends=(FlatA.name, FlatB.name), samples=1, outputs=("rgb", "depth"))
    rep.save(folder / "xc")


#: writers of a folder of files: name -> call(parent folder)
FOLDER_WRITERS = {
    "render_frames": _render_frames,
    "compare-report": _compare_report,
    "crosscheck-report": _crosscheck_report,
}


def _tree(folder: Path) -> tuple[dict[str, int], dict[str, int]]:
    files, dirs = {}, {}
    for p in sorted(folder.rglob("*")):
        (dirs if p.is_dir() else files)[str(p.relative_to(folder))] = _mode(p)
    return files, dirs


# -- modes ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("writer", list(FILE_WRITERS))
def test_new_file_gets_the_umask_mode(writer, umask, tmp_path):
    name, call = FILE_WRITERS[writer]
    call(tmp_path / name)
    expected = 0o666 & ~umask
    assert {p.name: oct(_mode(p)) for p in tmp_path.iterdir()} == {name: oct(expected)}


@pytest.mark.parametrize("writer", list(FOLDER_WRITERS))
def test_every_file_of_a_folder_writer_gets_the_umask_mode(writer, umask, tmp_path, flat_backends):
    FOLDER_WRITERS[writer](tmp_path)
    files, dirs = _tree(tmp_path)
    assert len(files) >= 3, files
    assert {k: oct(v) for k, v in files.items()} == {k: oct(0o666 & ~umask) for k in files}
    assert {k: oct(v) for k, v in dirs.items()} == {k: oct(0o777 & ~umask) for k in dirs}
    assert not [k for k in files if Path(k).name.startswith(".")], f"temporary files left: {files}"


def test_render_frames_mp4_has_the_mode_of_its_frames(tmp_path, flat_backends):
    """The regression of issue 13: the MP4 was 0600 (a mkstemp file) next to 0644 frames."""
    old = os.umask(0o022)
    try:
        _render_frames(tmp_path)
    finally:
        os.umask(old)
    assert _mode(tmp_path / "v.mp4") == _mode(tmp_path / "frames" / "frame_00000.png") == 0o644


@pytest.mark.parametrize("writer", ["result-png", "result-npz", "scene-npz", "video-mp4", "atomic_write"])
def test_overwriting_keeps_the_old_permission_bits(writer, tmp_path):
    """Like open(path, "w"): a file the user made private (or group-writable) keeps its mode."""
    name, call = FILE_WRITERS[writer]
    target = tmp_path / name
    for kept in (0o600, 0o664):
        target.write_bytes(b"OLD")
        os.chmod(target, kept)
        call(target)
        assert target.read_bytes() != b"OLD"
        assert oct(_mode(target)) == oct(kept)
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_a_writer_that_recreates_the_file_still_gets_the_mode(umask, tmp_path):
    """A writer may replace the temporary file by one of its own (here mode 0600): the mode is put back."""

    def writer(tmp: str) -> None:
        os.unlink(tmp)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.write(fd, b"x")
        os.close(fd)

    p = atomic_write(tmp_path / "x.bin", writer)
    assert _mode(p) == 0o666 & ~umask


def test_writers_never_touch_the_process_umask(tmp_path, flat_backends, monkeypatch):
    """os.umask changes the umask of every thread: no writer may call it (not even to read it)."""
    pytest.importorskip("imageio_ffmpeg", reason="the MP4 writer needs the 'video' extra (imageio-ffmpeg)")
    calls = []

    def forbidden(mask):
        calls.append(mask)
        raise AssertionError("os.umask called by a writer")

    monkeypatch.setattr(os, "umask", forbidden)
    for i, (name, call) in enumerate(FILE_WRITERS.values()):
        if name == "x.exr" and importlib.util.find_spec("OpenEXR") is None:
            continue  # the .exr writer is covered by test_new_file_gets_the_umask_mode where installed
        call(tmp_path / f"{i}{name}")
    for i, call in enumerate(FOLDER_WRITERS.values()):
        (tmp_path / f"f{i}").mkdir()
        call(tmp_path / f"f{i}")
    assert calls == []


def test_saving_in_one_thread_never_changes_the_mode_of_files_created_in_another(tmp_path):
    """A background thread creating files with open() while results are saved must always see its files
    with mode 0o666 & ~umask (the old os.umask(0) read opened a window where they got 0666)."""
    old_umask = os.umask(0o027)
    old_switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: widen any race
    bg = tmp_path / "bg"
    bg.mkdir()
    stop = threading.Event()
    seen: list[int] = []
    wrong: list[str] = []

    def create_files() -> None:
        i = 0
        while not stop.is_set():
            p = bg / f"f{i % 64}"
            with open(p, "w"):
                pass
            m = _mode(p)
            seen.append(m)
            if m != 0o640:
                wrong.append(f"{p.name}: {oct(m)}")
            p.unlink()
            i += 1

    thread = threading.Thread(target=create_files, daemon=True)
    r = _result()
    saves = 0
    try:
        thread.start()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:
            r.save(tmp_path / "x.npz")
            atomic_write(tmp_path / "y.txt", lambda tmp: None)
            saves += 2
    finally:
        stop.set()
        thread.join(10)
        sys.setswitchinterval(old_switch)
        os.umask(old_umask)
    assert saves > 50 and len(seen) > 50, (saves, len(seen))
    assert wrong == [], f"{len(wrong)} of {len(seen)} files ignored the umask: {wrong[:5]}"
    assert _mode(tmp_path / "x.npz") == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bg", "x.npz", "y.txt"]


# -- errors -----------------------------------------------------------------------------------------
def _bad_targets(tmp_path: Path, name: str) -> dict[str, tuple[Path, int]]:
    (tmp_path / f"folder{Path(name).suffix}").mkdir()
    (tmp_path / "a_file").write_bytes(b"")
    return {
        "nul-byte": (tmp_path / f"a\x00b{Path(name).suffix}", errno.EINVAL),
        "existing-folder": (tmp_path / f"folder{Path(name).suffix}", errno.EISDIR),
        "300-char-name": (tmp_path / ("n" * 296 + Path(name).suffix), errno.ENAMETOOLONG),
        "missing-folder": (tmp_path / "missing" / name, errno.ENOENT),
        "folder-is-a-file": (tmp_path / "a_file" / name, errno.ENOTDIR),
    }


CASES = ["nul-byte", "existing-folder", "300-char-name", "missing-folder", "folder-is-a-file"]


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("writer", list(FILE_WRITERS))
def test_unwritable_paths_raise_output_error_naming_the_path(writer, case, tmp_path):
    name, call = FILE_WRITERS[writer]
    target, code = _bad_targets(tmp_path, name)[case]
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(OutputError) as info:
        call(target)
    exc = info.value
    assert isinstance(exc, OSError) and isinstance(exc, bf.BlendifyError)
    assert repr(str(target)) in str(exc), str(exc)
    assert exc.errno == code and exc.filename == str(target)
    if case == "missing-folder":
        assert isinstance(exc, MissingFolderError) and isinstance(exc, bf.InvalidSceneError)
        assert "does not exist" in str(exc)
    assert sorted(p.name for p in tmp_path.iterdir()) == before, "a temporary file was left behind"
    assert not any(p.name.startswith(".") for p in tmp_path.rglob("*"))


def _unprivileged(fn) -> tuple[str, ...]:
    """Run ``fn()`` in a forked child as user 'nobody' (root ignores permission bits); returns what it
    raised as (class names of the MRO, message) or ("ok",)."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        os.close(r)
        try:
            os.setgroups([])
            os.setgid(65534)
            os.setuid(65534)
            fn()
            out = "ok"
        except BaseException as exc:  # noqa: BLE001 - reported to the parent
            out = "\t".join([c.__name__ for c in type(exc).__mro__] + [str(exc)])
        os.write(w, out.encode("utf-8", "backslashreplace"))
        os._exit(0)
    os.close(w)
    chunks = []
    while chunk := os.read(r, 65536):
        chunks.append(chunk)
    os.close(r)
    os.waitpid(pid, 0)
    return tuple(b"".join(chunks).decode().split("\t"))


@pytest.mark.parametrize("writer", [w for w in FILE_WRITERS if w != "result-exr"])
def test_read_only_folder_raises_output_error(writer, tmp_path):
    name, call = FILE_WRITERS[writer]
    if writer == "video-mp4":
        pytest.importorskip("imageio_ffmpeg", reason="the MP4 writer needs the 'video' extra (imageio-ffmpeg)")
        import imageio.v2  # noqa: F401  (imported before the forked child, which may not read the venv)
    import PIL.PngImagePlugin  # noqa: F401

    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.geteuid() != 0:
            with pytest.raises(OutputError) as info:
                call(ro / name)
            names, message = [c.__name__ for c in type(info.value).__mro__], str(info.value)
        else:  # root writes anywhere: try as 'nobody', from inside the folder (its parents are 0700)
            cwd = os.getcwd()
            os.chdir(ro)
            try:
                *names, message = _unprivileged(lambda: call(Path(name)))
            finally:
                os.chdir(cwd)
        assert "OutputError" in names and "OSError" in names, (names, message)
        assert repr(name) in message or repr(str(ro / name)) in message, message
        assert "ermission denied" in message, message
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_a_write_failing_half_way_is_an_output_error_with_the_cause(tmp_path):
    def disk_full(tmp: str) -> None:
        Path(tmp).write_bytes(b"PARTIAL")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OutputError, match="No space left on device") as info:
        atomic_write(tmp_path / "x.bin", disk_full)
    assert info.value.errno == errno.ENOSPC and repr(str(tmp_path / "x.bin")) in str(info.value)
    assert isinstance(info.value.__cause__, OSError)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("writer", list(FOLDER_WRITERS))
def test_folder_writers_raise_output_error(writer, tmp_path, flat_backends):
    (tmp_path / "a_file").write_bytes(b"")
    call = FOLDER_WRITERS[writer]
    with pytest.raises(OutputError) as info:
        call(tmp_path / "a_file")  # the writer's folder would be created inside a file
    assert isinstance(info.value, OSError)
    assert str(tmp_path / "a_file") in str(info.value), str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_ensure_folder_errors(tmp_path):
    (tmp_path / "f").write_bytes(b"")
    with pytest.raises(OutputError, match="a file of that name exists"):
        ensure_folder(tmp_path / "f", arg="frames_dir")
    with pytest.raises(OutputError, match="frames_dir: .*NUL"):
        ensure_folder(str(tmp_path / "a\x00"), arg="frames_dir")
    assert ensure_folder(tmp_path / "a" / "b").is_dir()


def test_a_long_name_that_fits_is_written(tmp_path):
    """The temporary file's name is shortened to fit; the final name keeps every character."""
    name = "n" * 251 + ".npz"
    _result().save(tmp_path / name)
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_output_error_keeps_path_and_errno_across_processes():
    exc = MissingFolderError("path: cannot write 'a/b.png': the folder 'a' does not exist", "a/b.png", 2)
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is MissingFolderError
    assert (str(back), back.filename, back.errno) == (str(exc), "a/b.png", 2)
    assert bf.OutputError is OutputError


def test_atomic_output_commit_and_discard(tmp_path):
    out = AtomicOutput(tmp_path / "x.txt")
    assert out.tmp.parent == tmp_path and out.tmp.name.startswith(".x.txt.") and out.tmp.suffix == ".txt"
    out.tmp.write_text("ok")
    assert out.commit() == tmp_path / "x.txt"
    with pytest.raises(OutputError, match="already committed"):
        out.commit()
    out2 = AtomicOutput(tmp_path / "y.txt")
    out2.discard()
    out2.discard()  # twice is fine
    assert [p.name for p in tmp_path.iterdir()] == ["x.txt"]
