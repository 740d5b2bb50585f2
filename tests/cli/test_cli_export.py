"""``blendify export`` and ``blendify show``: the scene file's formats from the command line, with the
exit codes and one-line errors of every subcommand."""

from __future__ import annotations

import json

import pytest

from blendify_core.cli.main import main
from blendify_core.testing import textured_quad_scene


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "quad.npz"
    textured_quad_scene((32, 32)).save(path)
    return path


def test_export_writes_the_format_of_the_suffix(scene_file, tmp_path, capsys):
    with pytest.warns(UserWarning, match="world light"):
        assert main(["export", str(scene_file), str(tmp_path / "quad.gltf")]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {tmp_path / 'quad.gltf'}"
    assert json.loads((tmp_path / "quad.gltf").read_text())["asset"]["version"] == "2.0"
    assert (tmp_path / "quad.bin").is_file()
    assert main(["export", str(scene_file), str(tmp_path / "quad.html")]) == 0
    assert "blendify-glb" in (tmp_path / "quad.html").read_text()


def test_show_writes_the_page_without_a_browser(scene_file, tmp_path, capsys):
    out = tmp_path / "view.html"
    assert main(["show", str(scene_file), "--viewer", "html", "-o", str(out), "--no-browser"]) == 0
    assert out.is_file() and capsys.readouterr().out.strip() == f"wrote {out}"


@pytest.mark.parametrize(
    "argv",
    [
        ["export", "{missing}", "{tmp}/x.glb"],
        ["export", "{scene}", "{tmp}/x.obj"],
        ["show", "{missing}"],
        ["show", "{scene}", "--viewer", "vtk"],
    ],
)
def test_bad_input_exits_2_with_one_error_line(argv, scene_file, tmp_path, capsys):
    args = [a.format(missing=tmp_path / "nope.npz", scene=scene_file, tmp=tmp_path) for a in argv]
    try:
        code = main(args)
    except SystemExit as ex:  # argparse's choices
        code = int(ex.code or 0)
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"blendify {argv[0]}: error: "), err
