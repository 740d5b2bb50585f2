"""`import blendify_core` (and every public core submodule) loads numpy/scipy only: no engine, no GUI
library, no optional heavy dependency. Checked in a fresh child interpreter, stage by stage."""

from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import pytest

import blendify_core

FORBIDDEN = ("bpy", "mitsuba", "drjit", "pyrender", "OpenGL", "pyglet", "trimesh", "PIL", "matplotlib")
# modules that exist to talk to heavy libraries on purpose (they import them lazily anyway)
EXCLUDED = {"cli", "cli.main", "cli.demo", "ir.from_trimesh", "__main__"}


def _submodules() -> list[str]:
    names = [
        m.name.removeprefix("blendify_core.")
        for m in pkgutil.walk_packages(blendify_core.__path__, prefix="blendify_core.")
    ]
    names = [n for n in names if n not in EXCLUDED]
    assert "ir.scene" in names and "pipeline.render" in names and "testing" in names, names
    return sorted(names)


STAGES = {
    "import blendify_core": "import blendify_core",
    "import every public submodule": "\n".join(f"import blendify_core.{n}" for n in _submodules()),
    "list backends": "import blendify_core as bf\nbf.backend_names()",
    "build, fingerprint and analyse a scene": (
        "import blendify_core as bf\n"
        "from blendify_core.testing import every_feature_scene\n"
        "from blendify_core.pipeline.capabilities import scene_features\n"
        "s = every_feature_scene()\n"
        "s.fingerprint()\n"
        "bf.analyse_effects(s)\n"
        "scene_features(s, ('rgb', 'depth'))\n"
    ),
}


@pytest.fixture(scope="module")
def loaded_per_stage() -> dict[str, list[str]]:
    """Run every stage in ONE fresh interpreter, recording sys.modules after each (stages only add)."""
    lines = ["import sys, json", "out = {}"]
    for stage, code in STAGES.items():
        lines.append(code)
        lines.append(f"out[{stage!r}] = sorted(sys.modules)")
    lines.append("print(json.dumps(out))")
    res = subprocess.run([sys.executable, "-c", "\n".join(lines)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, f"child failed:\n{res.stderr}"
    return json.loads(res.stdout.strip().splitlines()[-1])


def _offenders(modules: list[str]) -> list[str]:
    return sorted(m for m in modules if m.split(".")[0] in FORBIDDEN)


@pytest.mark.parametrize("stage", list(STAGES))
def test_stage_loads_no_engine(loaded_per_stage, stage):
    loaded = loaded_per_stage[stage]
    assert "blendify_core" in loaded and "numpy" in loaded
    assert _offenders(loaded) == [], f"{stage!r} loaded {_offenders(loaded)}"


def test_every_public_submodule_was_imported(loaded_per_stage):
    loaded = set(loaded_per_stage["import every public submodule"])
    missing = [n for n in _submodules() if f"blendify_core.{n}" not in loaded]
    assert missing == []


def test_the_check_would_notice_an_engine(loaded_per_stage):
    """Guard against a vacuous test: the detector flags a forbidden module."""
    assert _offenders(["numpy", "PIL.Image", "OpenGL.GL", "bpy"]) == ["OpenGL.GL", "PIL.Image", "bpy"]
