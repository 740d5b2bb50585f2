"""One exit-code table for every ``blendify`` subcommand, one-line "error:" messages, backend choices
listed, NullHandlers on every package logger."""

from __future__ import annotations

import importlib
import logging
from typing import Any

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.cli.main import main
from blendify_core.errors import EXIT_CODES, exit_code
from blendify_core.pipeline.backend import Backend
from blendify_core.registry import BackendStatus, register_backend, unregister_backend


def _run(argv: list[str]) -> int:
    """The process exit code of ``blendify ARGV`` (argparse exits through SystemExit)."""
    try:
        return main(argv)
    except SystemExit as ex:
        return int(ex.code or 0)


@pytest.mark.parametrize(
    "argv",
    [
        ["render", "{missing}"],
        ["batch", "{missing}"],
        ["crosscheck", "{missing}"],
        ["crosscheck", "-o", "{tmp}/out", "{missing}"],
    ],
)
def test_missing_scene_file_exits_2_with_error_prefix_everywhere(argv, tmp_path, capsys):
    args = [a.format(missing=tmp_path / "nope.npz", tmp=tmp_path) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"blendify {argv[0]}: error: ") and "nope.npz" in err[0]


@pytest.mark.parametrize(
    "argv",
    [
        ["render", "s.npz", "--nonsense"],
        ["crosscheck", "s.npz", "--nonsense"],
        ["batch"],
        ["render", "s.npz", "-q", "x"],
    ],
)
def test_bad_usage_exits_2_with_one_error_line(argv, capsys):
    assert _run(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"blendify {argv[0]}: error: ")


def test_backend_option_lists_the_choices(capsys):
    names = bf.registry.backend_names()
    with pytest.raises(SystemExit) as ex:
        main(["render", "s.npz", "-b", "blender"])
    assert ex.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'blender'" in err and all(repr(n) in err for n in names)
    for command in ("render", "demo"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = capsys.readouterr().out
        assert "one of: " + ", ".join(names) in " ".join(out.split())


@pytest.mark.parametrize("command", ["render", "batch", "demo", "info", "crosscheck"])
def test_every_subcommand_documents_the_exit_codes(command, capsys):
    assert _run([command, "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "exit codes (every subcommand):" in out
    for value, text in EXIT_CODES.items():
        assert f"{value} {' '.join(text.split())}" in out


class _Unavailable(Backend):
    name = "i22a-unavailable"

    @classmethod
    def probe(cls) -> BackendStatus:
        return BackendStatus(False, "engine not installed (test)", None)

    def translate(self, scene: Any, settings: Any) -> Any:  # pragma: no cover - never reached
        raise AssertionError

    def render(self, native: Any, settings: Any) -> Any:  # pragma: no cover - never reached
        raise AssertionError


@pytest.fixture
def unavailable_backend():
    register_backend(_Unavailable.name, _Unavailable)
    yield _Unavailable.name
    unregister_backend(_Unavailable.name)


def test_unavailable_backend_exits_3(unavailable_backend, tmp_path, capsys):
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)))
    scene.set_perspective_camera((16, 12), fov_x=np.deg2rad(40), translation=(0, 0, 4))
    scene.lights.add_point(100.0, translation=(0, 2, 3))
    scene.save(tmp_path / "s.npz")
    code = main(["render", str(tmp_path / "s.npz"), "-b", unavailable_backend, "-o", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert code == 3 and err.startswith("blendify render: error: ") and "engine not installed (test)" in err
    assert not (tmp_path / "o.png").exists()


def test_exit_code_of_each_error_kind():
    assert exit_code(bf.InvalidSceneError("x")) == 2
    assert exit_code(FileNotFoundError("x")) == 2
    assert exit_code(bf.BackendUnavailableError("x")) == 3
    assert exit_code(bf.RenderError("x")) == 1
    assert exit_code(bf.UnsupportedFeatureError("x")) == 1
    assert exit_code(bf.OutputError("x")) == 1
    assert exit_code(KeyboardInterrupt()) == 130


@pytest.mark.parametrize("package", ["blendify_core", "blendify_blender", "blendify_mitsuba", "blendify_pyrender"])
def test_every_package_logger_has_a_null_handler(package):
    importlib.import_module(package)
    handlers = logging.getLogger(package).handlers
    assert any(isinstance(h, logging.NullHandler) for h in handlers), f"{package}: {handlers}"


def test_render_device_strict_without_gpu_exits_3(tmp_path, capsys, monkeypatch):
    if not bf.available_backends()["cycles"].available:
        pytest.skip("cycles unavailable")
    from blendify_blender import session as cycles_session

    from blendify_core import testing

    monkeypatch.setattr(cycles_session, "list_gpu_devices", lambda: [])
    testing.plane_scene("sun", resolution=(8, 8)).save(tmp_path / "s.npz")
    argv = ["render", str(tmp_path / "s.npz"), "-b", "cycles", "-s", "1", "-o", str(tmp_path / "o.png")]
    assert main([*argv, "--device", "gpu", "--strict"]) == 3
    err = capsys.readouterr().err
    assert err.startswith("blendify render: error: cycles: device='gpu' is unavailable here")
    assert not (tmp_path / "o.png").exists()
    with pytest.warns(UserWarning, match="device='gpu' is unavailable"):
        assert main([*argv, "--device", "gpu"]) == 0
    assert (tmp_path / "o.png").is_file()
