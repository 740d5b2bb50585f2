"""A synced environment stays synced: uv must not reinstall bpy on every ``uv run``.

bpy 5.0.1's installed WHEEL file carries the tag ``cp39-cp39-manylinux_2_28_x86_64`` (its file name says
cp311); uv then reinstalls bpy on every sync, deleting it under running renders. blendify-blender installs
``_blendify_bpy_tags`` + ``_blendify_bpy_tags.pth``, which repair the tag at interpreter start-up.

The fast tests check the repair on a fake dist-info; the slow one syncs a throwaway environment, renders
in it and runs ``uv run`` beside the render.
"""

from __future__ import annotations

import base64
import errno
import hashlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[3]
BLENDER_DIR = ROOT / "backends" / "blender"
BAD = "Tag: cp39-cp39-manylinux_2_28_x86_64"
GOOD = "Tag: cp311-cp311-manylinux_2_28_x86_64"


def _load_tags_module() -> types.ModuleType:
    """The repository's ``_blendify_bpy_tags`` (loaded from its file: the code under test, whatever is installed)."""
    spec = importlib.util.spec_from_file_location("_bpy_tags_under_test", BLENDER_DIR / "_blendify_bpy_tags.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture
def tags() -> types.ModuleType:
    if sys.implementation.name != "cpython" or sys.version_info[:2] != (3, 11):
        pytest.skip(f"the bpy tag repair acts on CPython 3.11 only (this is {sys.version.split()[0]})")
    return _load_tags_module()


def _fake_dist_info(site: Path, tag_line: str) -> Path:
    d = site / "bpy-5.0.1.dist-info"
    d.mkdir(parents=True)
    wheel = f"Wheel-Version: 1.0\nGenerator: setuptools (80.9.0)\nRoot-Is-Purelib: false\n{tag_line}\n\n"
    (d / "WHEEL").write_text(wheel)
    (d / "METADATA").write_text("Metadata-Version: 2.1\nName: bpy\nVersion: 5.0.1\n")
    (d / "RECORD").write_text(
        "bpy/__init__.py,sha256=abc,10\n"
        f"bpy-5.0.1.dist-info/WHEEL,sha256=GgX20VmKcCojXA25QwkMazru5rPDAsLYhjc0VMiPAHQ,{len(wheel)}\n"
        "bpy-5.0.1.dist-info/RECORD,,\n"
    )
    return d


def test_bad_tag_is_rewritten_atomically_with_record(tags, tmp_path):
    d = _fake_dist_info(tmp_path, BAD)
    (d / "WHEEL").chmod(0o640)
    before = (d / "WHEEL").read_text()
    inode = (d / "WHEEL").stat().st_ino
    assert tags.fix(site_dirs=[str(tmp_path)]) is True
    after = (d / "WHEEL").read_text()
    assert after == before.replace(BAD, GOOD)
    # a new file moved over the old one (uv hard-links installed files to its cache: never write in place)
    assert (d / "WHEEL").stat().st_ino != inode
    assert (d / "WHEEL").stat().st_mode & 0o777 == 0o640
    digest = base64.urlsafe_b64encode(hashlib.sha256(after.encode()).digest()).rstrip(b"=").decode()
    record = (d / "RECORD").read_text().splitlines()
    assert record == [
        "bpy/__init__.py,sha256=abc,10",
        f"bpy-5.0.1.dist-info/WHEEL,sha256={digest},{len(after.encode())}",
        "bpy-5.0.1.dist-info/RECORD,,",
    ]
    assert sorted(p.name for p in d.iterdir()) == ["METADATA", "RECORD", "WHEEL"]  # no temporary file left
    # the second call finds nothing to do
    assert tags.fix(site_dirs=[str(tmp_path)]) is False
    assert (d / "WHEEL").read_text() == after


def test_good_or_other_tags_are_left_alone(tags, tmp_path):
    for i, line in enumerate((GOOD, "Tag: cp39-cp39-macosx_11_0_arm64", "Tag: cp39-cp39-manylinux_2_28_x86_64x")):
        site = tmp_path / str(i)
        d = _fake_dist_info(site, line)
        stat = (d / "WHEEL").stat()
        record = (d / "RECORD").read_bytes()
        assert tags.fix(site_dirs=[str(site)]) is False, line
        assert (d / "WHEEL").stat().st_ino == stat.st_ino and (d / "WHEEL").stat().st_mtime_ns == stat.st_mtime_ns
        assert (d / "RECORD").read_bytes() == record


def test_only_bpy_and_only_cpython_311(tags, tmp_path, monkeypatch):
    other = tmp_path / "other" / "numpy-1.26.4.dist-info"
    other.mkdir(parents=True)
    (other / "WHEEL").write_text(f"Wheel-Version: 1.0\n{BAD}\n")
    assert tags.fix(site_dirs=[str(tmp_path / "other"), str(tmp_path / "missing")]) is False
    assert BAD in (other / "WHEEL").read_text()
    d = _fake_dist_info(tmp_path / "site", BAD)
    fake_sys = types.SimpleNamespace(
        implementation=types.SimpleNamespace(name="cpython"), version_info=(3, 12, 1), path=[]
    )
    monkeypatch.setattr(tags, "sys", fake_sys)
    assert tags.fix(site_dirs=[str(tmp_path / "site")]) is False
    assert BAD in (d / "WHEEL").read_text()


class _ReadOnlyOS:
    """``os`` as seen on a read-only file system: creating a file fails."""

    def __getattr__(self, name):
        return getattr(os, name)

    def open(self, path, flags, *args):
        if flags & os.O_CREAT:
            raise OSError(errno.EROFS, "Read-only file system", path)
        return os.open(path, flags, *args)


def test_never_raises_when_the_file_cannot_be_written(tags, tmp_path, monkeypatch, capsys):
    d = _fake_dist_info(tmp_path, BAD)
    before = (d / "WHEEL").read_bytes()
    if os.geteuid() != 0:  # a really read-only dist-info (root ignores permission bits)
        (d / "WHEEL").chmod(0o444)
        d.chmod(0o555)
        try:
            assert tags.fix(site_dirs=[str(tmp_path)]) is False
        finally:
            d.chmod(0o755)
        assert (d / "WHEEL").read_bytes() == before
    monkeypatch.setattr(tags, "os", _ReadOnlyOS())
    assert tags.fix(site_dirs=[str(tmp_path)]) is False
    assert (d / "WHEEL").read_bytes() == before
    assert sorted(p.name for p in d.iterdir()) == ["METADATA", "RECORD", "WHEEL"]
    monkeypatch.undo()
    (d / "WHEEL").unlink()
    (d / "WHEEL").mkdir()  # an unreadable WHEEL
    assert tags.fix_dist_info(str(d)) is False
    assert capsys.readouterr() == ("", "")


def test_record_failure_keeps_the_fixed_tag(tags, tmp_path):
    d = _fake_dist_info(tmp_path, BAD)
    (d / "RECORD").unlink()
    assert tags.fix(site_dirs=[str(tmp_path)]) is True
    assert GOOD in (d / "WHEEL").read_text()


def test_packaging_ships_the_module_and_the_pth():
    """The pinned bpy version, the force-included files and the .pth line agree with the module."""
    mod = _load_tags_module()
    project = tomllib.loads((BLENDER_DIR / "pyproject.toml").read_text())
    pins = [d for d in project["project"]["dependencies"] if re.match(r"bpy\s*==", d)]
    assert pins == [f"bpy=={mod.BPY_VERSION}"], "bump BPY_VERSION (and check the new wheel's tag) with the bpy pin"
    force = project["tool"]["hatch"]["build"]["targets"]["wheel"]["force-include"]
    assert force == {
        "_blendify_bpy_tags.py": "_blendify_bpy_tags.py",
        "_blendify_bpy_tags.pth": "_blendify_bpy_tags.pth",
    }
    pth = (BLENDER_DIR / "_blendify_bpy_tags.pth").read_text().splitlines()
    assert pth == ["import _blendify_bpy_tags; _blendify_bpy_tags.fix()"]
    source = (BLENDER_DIR / "_blendify_bpy_tags.py").read_text()
    imports = set(re.findall(r"^\s*import (\w+)", source, flags=re.M)) | set(
        re.findall(r"^\s*from (\S+) import", source, flags=re.M)
    )
    assert imports <= {"os", "sys", "base64", "hashlib"}, imports  # start-up cost: stdlib basics only


# -- the real thing: a throwaway environment, a render, and `uv run` beside it --------------------------------

_RENDER = """
import sys, time
import numpy as np
import blendify_core as bf
from blendify_core.testing import primitives_scene
print("start", flush=True)
t = time.perf_counter()
r = bf.render(primitives_scene((128, 96)), backend="cycles", samples=int(sys.argv[1]), threads=1)
rgb = np.asarray(r.rgb)
print("rendered", rgb.shape, float(rgb.mean()), round(time.perf_counter() - t, 1), flush=True)
"""

_CHANGES = re.compile(r"^\s*(Installed|Uninstalled|Prepared|[~+-] )", re.M)


def _uv_env(venv: Path) -> dict[str, str]:
    drop = {"VIRTUAL_ENV", "UV_NO_SYNC", "UV_PROJECT_ENVIRONMENT", "PYTHONPATH", "PYTHONHOME", "UV_FROZEN"}
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env["UV_PROJECT_ENVIRONMENT"] = str(venv)
    return env


@pytest.mark.slow
def test_uv_run_beside_a_render_installs_nothing(tmp_path):
    uv = shutil.which("uv")
    if uv is None:
        print("skipping: uv is not on PATH")
        pytest.skip("uv is not on PATH")
    venv = tmp_path / "venv"
    env = _uv_env(venv)
    flags = ["--frozen", "--no-dev", "--extra", "blender"]
    sync = subprocess.run([uv, "sync", *flags], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert sync.returncode == 0, sync.stderr
    python = venv / "bin" / "python"
    sites = sorted(venv.glob("lib/python3*/site-packages"))  # no interpreter yet: it would run the .pth
    assert len(sites) == 1, sites
    site = sites[0]
    # the editable install of the workspace member carries the start-up hook
    assert (site / "_blendify_bpy_tags.pth").is_file() and (site / "_blendify_bpy_tags.py").is_file()
    wheel = site / "bpy-5.0.1.dist-info" / "WHEEL"
    print(f"bpy WHEEL after sync: {[ln for ln in wheel.read_text().splitlines() if ln.startswith('Tag:')]}")

    render = subprocess.Popen(
        [python, "-c", _RENDER, "512"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert render.stdout is not None
        first = render.stdout.readline()  # the interpreter has started (and run the .pth): bpy comes next
        assert first.strip() == "start", first + (render.stderr.read() if render.stderr else "")
        assert GOOD in wheel.read_text(), "the interpreter start-up did not repair bpy's WHEEL tag"
        t0 = time.perf_counter()
        run = subprocess.run(
            [uv, "run", *flags, "python", "-c", "pass"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
        )
        t_run = time.perf_counter() - t0
        still_rendering = render.poll() is None
        out, err = render.communicate(timeout=600)
    finally:
        if render.poll() is None:
            render.kill()
            render.wait()
    print(f"uv run beside the render: {t_run:.2f} s; render: {out.strip()}")
    assert run.returncode == 0, run.stderr
    assert not _CHANGES.search(run.stdout + run.stderr), f"uv run changed the environment:\n{run.stderr}"
    assert still_rendering, "the render ended before uv run did: the test did not overlap them"
    assert render.returncode == 0, err[-3000:]
    assert out.splitlines()[-1].startswith("rendered (96, 128, 3)"), out
    assert float(out.split()[-2]) > 0.01, out  # a lit picture, not an empty one
