"""Every example runs, at tiny settings, and writes what it says it writes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
TINY = ["--size", "48", "--samples", "4"]

CASES = {
    "01_figure1_panels.py": (
        TINY,
        [
            "colour.png",
            "depth.png",
            "albedo.png",
            "metal.png",
            "plastic.png",
            "wireframe.png",
            "pointcloud.png",
            "lighting.png",
        ],
    ),
    "02_camera_colored_pointcloud_video.py": (TINY + ["--frames", "3"], ["orbit.mp4", "orbit_frames/frame_00002.png"]),
    "03_textured_mesh.py": (TINY, ["textured_mesh.png"]),
    "04_materials_shadow_catcher.py": (TINY, ["materials.png", "materials_on_white.png"]),
    "05_per_face_materials.py": (TINY, ["per_face_materials.png"]),
    "06_three_backends.py": (TINY, ["three_backends"]),
    "07_preview_then_final.py": (TINY, ["preview.png", "final.png"]),
    "08_export_and_view.py": (TINY, ["scene.glb", "scene.gltf", "scene.bin", "scene.xml", "scene_files", "view.html"]),
}


def test_every_example_is_covered():
    scripts = {p.name for p in EXAMPLES.glob("[0-9][0-9]_*.py")}
    assert scripts == set(CASES), f"examples without a runner case: {scripts ^ set(CASES)}"


@pytest.mark.parametrize("script", sorted(CASES))
def test_example_runs(script, tmp_path):
    args, expected = CASES[script]
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script), "-o", str(tmp_path), *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, f"{script} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    for name in expected:
        assert (tmp_path / name).exists(), (
            f"{script} did not write {name}; wrote {sorted(p.name for p in tmp_path.iterdir())}"
        )
    assert proc.stdout.strip(), f"{script} printed nothing"
