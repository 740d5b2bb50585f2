"""Third-party .blend files (tests/third_party/blend, SOURCES.md): attached as a new user would, rendered by
Blender itself and by blendify's Cycles backend -- the same picture (benchmarks/blend_fidelity.py measures
all of them with Mitsuba and pyrender too).

Committed files (open licences) always run; files under ``$BLENDIFY_THIRD_PARTY_DIR/blend`` (cache-only)
run when the variable names a folder that has them.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from blendify_blender.blendfile import BlendAttachWarning, attach_blend
from blendify_blender.blendfile.reference import blender_render, prepare_blend

import blendify_core as bf
from blendify_core.ir.scene import Scene
from blendify_core.testing import THIRD_PARTY_DIR, THIRD_PARTY_ENV

COMMITTED = sorted((THIRD_PARTY_DIR / "blend").rglob("*.blend"))
#: one quick file in the default run; the rest are slow
QUICK = ("04_lights",)


def _cached() -> list[Path]:
    cache = os.environ.get(THIRD_PARTY_ENV)
    folder = Path(cache) / "blend" if cache else None
    return sorted(folder.rglob("*.blend")) if folder is not None and folder.is_dir() else []


def _params() -> list:
    out = [pytest.param(p, id=p.stem, marks=() if p.stem in QUICK else pytest.mark.slow) for p in COMMITTED + _cached()]
    if not _cached():
        reason = f"${THIRD_PARTY_ENV} is {'not set' if not os.environ.get(THIRD_PARTY_ENV) else 'without blend/'}"
        out.append(pytest.param(None, id="cache-only", marks=pytest.mark.skip(reason=f"cache-only files: {reason}")))
    return out


def test_the_committed_suite_is_there():
    assert len(COMMITTED) >= 10
    sources = (THIRD_PARTY_DIR / "SOURCES.md").read_text()
    for p in COMMITTED:
        assert f"blend/{p.parent.name}/{p.name}" in sources, f"{p.name} is not listed in SOURCES.md"
        assert (p.parent / "LICENSE.txt").is_file()


@pytest.mark.parametrize("path", COMMITTED, ids=[p.stem for p in COMMITTED])
def test_every_committed_file_attaches(path: Path, cycles):
    scene = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        added = attach_blend(scene, path, render_settings=True)
    assert len(added) >= 1
    assert added.render_settings is not None and added.render_settings["samples"] >= 1
    lines = scene.attachments[-1].approximations
    msgs = [str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning)]
    assert len(msgs) == (1 if lines else 0)  # whatever the parse lost is said once, line by line
    assert all(line in msgs[0] for line in lines)


@pytest.mark.parametrize("path", _params())
def test_cycles_renders_the_file_like_blender(path: Path, tmp_path: Path, cycles):
    copy = tmp_path / "prepared.blend"
    prepare_blend(path, copy, (40, 30), 8)
    _info, ref = blender_render(copy, tmp_path / "ref.exr")
    scene = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BlendAttachWarning)
        att = attach_blend(scene, copy, with_camera=True, render_settings=True)
    settings = {**att.render_settings, "outputs": ("rgba",)}
    res = bf.render(scene, backend="cycles", cycles_settings=att.cycles_settings, **settings)
    img = np.asarray(res.rgba)
    assert img.shape == ref.shape
    assert res.meta["translation"]["from_file"]["renderables"] == len(att)
    # the same engine, scene, settings and seed: the same samples (within float noise of the passes)
    assert np.abs(img - ref).mean() <= 1e-3 * max(float(np.abs(ref).mean()), 1e-3)


_READ_SETTINGS = """
import bpy, sys, json
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
cy = bpy.context.scene.cycles
print(json.dumps({"clamp_indirect": cy.sample_clamp_indirect, "filter_glossy": cy.blur_glossy,
                  "samples": cy.samples, "use_light_tree": cy.use_light_tree,
                  "light_sampling_threshold": cy.light_sampling_threshold, "version": list(bpy.data.version)}))
"""


def test_an_old_file_imports_the_settings_blender_opens_it_with(cycles):
    """04_lights was saved by Blender 2.78, before Cycles' indirect clamp (10) and Filter Glossy (1) defaults:
    Blender opens it with both off (Cycles' versioning of the file), and so does attach_blend(render_settings=
    True), although an appended scene skips that versioning and would read the current defaults."""
    from blendify_blender.blendfile.reference import run_bpy_script

    path = next(p for p in COMMITTED if p.stem == "04_lights")
    blender = run_bpy_script(_READ_SETTINGS, str(path))
    assert tuple(blender["version"]) <= (2, 79, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        added = attach_blend(Scene(), path, render_settings=True)
    assert added.render_settings["clamp_indirect"] == blender["clamp_indirect"] == 0.0
    assert added.render_settings["filter_glossy"] == blender["filter_glossy"] == 0.0
    assert added.render_settings["samples"] == blender["samples"]
    assert added.cycles_settings["use_light_tree"] is blender["use_light_tree"] is False
    assert added.cycles_settings["light_sampling_threshold"] == pytest.approx(blender["light_sampling_threshold"])


def test_crosscheck_with_the_files_biased_settings_is_limited_by_the_engine(tmp_path: Path, cycles):
    """04_lights asks for diffuse and glossy bounce limits of 4 (below its 12 bounces): Cycles applies them,
    Mitsuba has one depth limit for every kind. Rendered with the file's settings Mitsuba lists them in
    meta["approximations"], and a crosscheck with them reports the Cycles/Mitsuba pair limited by the engine
    (neither passed nor failed); with bf.render's own settings the pair is judged."""
    from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX
    from blendify_core.registry import available_backends

    if not available_backends()["mitsuba"].available:
        pytest.skip(f"mitsuba unavailable: {available_backends()['mitsuba'].reason}")
    path = next(p for p in COMMITTED if p.stem == "04_lights")
    copy = tmp_path / "prepared.blend"
    prepare_blend(path, copy, (32, 24), 8)
    scene = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BlendAttachWarning)
        att = attach_blend(scene, copy, with_camera=True, render_settings=True)
    biased = {k: v for k, v in att.render_settings.items() if k.startswith("clamp_") or k.endswith("_bounces")}
    assert (biased["diffuse_bounces"], biased["glossy_bounces"], biased["max_bounces"]) == (4, 4, 12)
    res = bf.render(scene, backend="mitsuba", samples=4, **biased)
    limits = [a for a in res.meta["approximations"] if a.startswith(ENGINE_LIMIT_PREFIX)]
    assert len(limits) == 1 and "bounce limits below max_bounces (diffuse 4, glossy 4)" in limits[0]
    kw = {"backends": ("cycles", "mitsuba"), "outputs": ("rgb",), "samples": 8, "passes": 1}
    rep = bf.crosscheck(scene, **kw, **biased)
    assert set(rep.limited) == {("cycles", "mitsuba")} and not rep.pairs and not rep.errors
    assert rep.limited[("cycles", "mitsuba")] == limits
    assert "cycles vs mitsuba: LIMITED BY THE ENGINE (not judged)" in rep.summary()
    plain = bf.crosscheck(scene, **kw)
    assert not plain.limited and list(plain.pairs) == [("cycles", "mitsuba")]
