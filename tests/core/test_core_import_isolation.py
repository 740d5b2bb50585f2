"""`import blendify_core` (and every public core submodule) loads numpy/scipy only: no engine, no GUI
library, no optional heavy dependency. Checked in a fresh child interpreter."""

from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import blendify_core

FORBIDDEN = ("bpy", "mitsuba", "drjit", "pyrender", "OpenGL", "pyglet", "trimesh", "PIL", "matplotlib")
# modules that exist to talk to heavy libraries on purpose (they import them lazily anyway)
EXCLUDED = {"cli", "trimesh_io", "__main__"}


def _submodules() -> list[str]:
    names = [m.name for m in pkgutil.iter_modules(blendify_core.__path__) if m.name not in EXCLUDED]
    assert "scene" in names and "render" in names and "testing" in names, names
    return sorted(names)


def _loaded_modules(code: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys, json\nprint(json.dumps(sorted(sys.modules)))"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, f"child failed:\n{out.stderr}"
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def _offenders(modules: set[str]) -> list[str]:
    return sorted(m for m in modules if m.split(".")[0] in FORBIDDEN)


def test_import_blendify_core_loads_no_engine():
    loaded = _loaded_modules("import blendify_core")
    assert "blendify_core" in loaded and "numpy" in loaded
    assert _offenders(loaded) == [], f"import blendify_core loaded {_offenders(loaded)}"


def test_import_every_public_submodule_loads_no_engine():
    subs = _submodules()
    code = "\n".join(f"import blendify_core.{name}" for name in subs)
    loaded = _loaded_modules(code)
    for name in subs:
        assert f"blendify_core.{name}" in loaded
    assert _offenders(loaded) == [], f"importing {subs} loaded {_offenders(loaded)}"


def test_registry_queries_load_no_engine():
    """Listing backends reads entry points only; it must not import any backend's engine."""
    loaded = _loaded_modules("import blendify_core as bf\nbf.backend_names()")
    engines = [m for m in _offenders(loaded) if m.split(".")[0] in ("bpy", "mitsuba", "drjit", "pyrender", "OpenGL")]
    assert engines == []


def test_building_a_scene_loads_no_engine():
    """Building, fingerprinting and analysing a scene stays numpy-only (the testing builders too,
    except the bunny which reads a PLY through trimesh)."""
    code = (
        "import blendify_core as bf\n"
        "from blendify_core.testing import every_feature_scene\n"
        "s = every_feature_scene()\n"
        "s.fingerprint()\n"
        "bf.analyse_effects(s)\n"
        "from blendify_core.features import scene_features\n"
        "scene_features(s, ('rgb', 'depth'))\n"
    )
    loaded = _loaded_modules(code)
    assert _offenders(loaded) == []
