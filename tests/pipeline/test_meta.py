"""``result.meta`` is typed: every key bf.render writes is documented in RenderMeta, the core's keys are
always there, and the core reads only the common timing names (it never folds a backend's own phases)."""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline import render as render_mod
from blendify_core.pipeline.meta import COMMON_TIMINGS, META_KEYS, TIMING_KEYS, RenderMeta, undocumented_keys
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import BackendStatus, available_backends, register_backend, unregister_backend
from blendify_core.testing import every_feature_scene, hard_cases, plane_scene

TESTS = Path(__file__).resolve().parents[1]

#: keys bf.render writes into every result, whatever the backend
CORE_KEYS = {
    "backend",
    "engine_version",
    "settings",
    "scene_fingerprint",
    "samples",
    "path_tracer",
    "effects",
    "simulated",
    "approximations",
    "estimated_error",
    "estimated_error_kind",
    "timings",
}


def _load(name: str, path: Path) -> Any:
    """A test helper module by file path (the fakes live beside their own test folders)."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


CoreFake = _load("meta_core_fake_backend", TESTS / "core" / "core_fake_backend.py").FakeBackend
BatchFake = _load("meta_batch_fake_backend", TESTS / "batch" / "batch_fake_backend.py").FakeBackend


class _Spy:
    """Mixin: remembers the meta keys the backend itself returned, so the keys bf.render added are known."""

    backend_keys: ClassVar[set[str]] = set()
    backend_timings: ClassVar[set[str]] = set()

    def render_scene(self, scene: Any, settings: Any) -> RenderResult:
        result = super().render_scene(scene, settings)  # type: ignore[misc]
        type(self).backend_keys = set(result.meta)
        type(self).backend_timings = set(result.meta.get("timings", {}))
        return result


class CoreSpy(_Spy, CoreFake):
    name = "meta-core-spy"


class TracerSpy(_Spy, CoreFake):
    """A path tracer with a minimum image size: exercises target_error passes and padding."""

    name = "meta-tracer-spy"
    path_tracer = True
    min_resolution = (40, 40)


class BatchSpy(_Spy, BatchFake):
    name = "meta-batch-spy"


SPIES = (CoreSpy, TracerSpy, BatchSpy)


@pytest.fixture(autouse=True)
def spies():
    for cls in SPIES:
        register_backend(cls.name, cls)
    yield
    bf.close_backends()
    for cls in SPIES:
        unregister_backend(cls.name)


def _distorted_scene() -> bf.Scene:
    s = plane_scene("sun", (40, 30))
    k = np.array([[40.0, 0, 20.5], [0, 40.0, 14.5], [0, 0, 1]])
    s.set_camera_from_opencv(k, np.eye(3), (0.0, 0.0, 5.0), (40, 30), distortion=(-0.1, 0.02, 0.001, 0.0))
    return s


def _clipped_scene() -> bf.Scene:
    s = plane_scene("sun", (16, 16))
    s.camera.far = 0.5  # every object beyond the far clip: a recorded warning
    return s


SCENES = {
    "plane": lambda: plane_scene("sun", (16, 12)),
    "every_feature": lambda: every_feature_scene((24, 18)),
    "distorted": _distorted_scene,
    "clipped": _clipped_scene,
    **{f"hard:{name}": builder for name, builder in hard_cases().items()},
}


def _render(scene: bf.Scene, backend: str, **kwargs: Any) -> RenderResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bf.render(scene, backend=backend, **kwargs)


def _check(result: RenderResult, spy: type[_Spy]) -> None:
    written = set(result.meta) - spy.backend_keys
    assert undocumented_keys({k: None for k in written}) == [], "bf.render wrote keys RenderMeta does not document"
    missing = CORE_KEYS - set(result.meta)
    assert not missing, f"core keys missing: {sorted(missing)}"
    timings = result.meta["timings"]
    assert {"translate", "render", "total"} <= set(timings)
    core_timings = set(timings) - spy.backend_timings
    assert core_timings <= set(TIMING_KEYS), f"undocumented timings {sorted(core_timings - set(TIMING_KEYS))}"
    assert all(isinstance(v, float) and v >= 0 for v in timings.values())


@pytest.mark.parametrize("case", sorted(SCENES))
def test_every_key_bf_render_writes_is_documented(case):
    scene = SCENES[case]()
    if scene.camera is None:
        pytest.skip(f"{case}: no camera, bf.render refuses it before writing any meta")
    result = _render(scene, CoreSpy.name, outputs=("rgb", "depth", "normal", "albedo", "instance"))
    _check(result, CoreSpy)


@pytest.mark.parametrize(
    "spy, kwargs",
    [
        (CoreSpy, {"outputs": ("depth",)}),
        (CoreSpy, {"target_error": 0.5}),  # not a path tracer: a recorded warning
        (TracerSpy, {"target_error": 0.5, "samples": 2}),  # passes, estimate, padding to 40x40
        (TracerSpy, {"quality": "preview", "effects": False}),
        (BatchSpy, {}),
        (BatchSpy, {"outputs": ("rgb", "depth")}),
    ],
)
def test_documented_keys_across_settings(spy, kwargs):
    result = _render(plane_scene("sun", (16, 12)), spy.name, **kwargs)
    _check(result, spy)
    if kwargs.get("target_error") and spy.path_tracer:
        assert {"passes", "target_reached"} <= set(result.meta)
        assert result.rgba.shape == (12, 16, 4)


def test_fallback_notes_and_recentring_are_documented(monkeypatch):
    """The automatic choice records the skipped backends; a far scene records its origin."""
    statuses = {"pyrender": BackendStatus(False, "switched off by the test"), CoreSpy.name: BackendStatus(True)}
    monkeypatch.setattr(render_mod, "available_backends", lambda: statuses)
    result = _render(hard_cases()["far_from_origin_1e6"](), None, quality="preview")
    assert result.meta["backend"] == CoreSpy.name
    assert result.meta["backend_fallback"] == ["pyrender: switched off by the test"]
    assert "recentred_origin" in result.meta
    _check(result, CoreSpy)


def test_meta_keys_are_the_typed_dict_keys():
    assert frozenset(RenderMeta.__annotations__) == META_KEYS
    assert CORE_KEYS <= META_KEYS
    assert set(COMMON_TIMINGS) <= set(TIMING_KEYS)
    assert undocumented_keys({"backend": "x", "made_up": 1, "also_made_up": 2}) == ["also_made_up", "made_up"]


class _OwnPhases(CoreFake):
    """Overrides render_scene and reports only phases of its own (no common names)."""

    name = "meta-own-phases"

    def render_scene(self, scene: Any, settings: Any) -> RenderResult:
        result = self.render(self.translate(scene, settings), settings)
        result.meta["timings"] = {"sync": 100.0, "gbuffer": 200.0, "read_outputs": 300.0}
        return result


def test_the_core_reads_only_common_timing_names():
    """A backend's own phase names are kept but never folded into translate / render / read_back."""
    register_backend(_OwnPhases.name, _OwnPhases)
    try:
        t = _render(plane_scene("sun", (8, 8)), _OwnPhases.name).meta["timings"]
    finally:
        bf.close_backends()
        unregister_backend(_OwnPhases.name)
    assert (t["sync"], t["gbuffer"], t["read_outputs"]) == (100.0, 200.0, 300.0)
    assert t["translate"] == 0.0
    assert 0.0 <= t["render"] < 100.0  # the measured call, not the backend's 200 s "gbuffer"
    assert "read_back" not in t
    assert t["total"] >= t["render"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pyrender", "mitsuba", "cycles"])
def test_real_backends_record_only_documented_keys(name):
    """Every key a real backend records is documented in RenderMeta, and it reports the common timings."""
    st = available_backends().get(name)
    if st is None or not st.available:
        reason = f"backend {name!r} unavailable: {st.reason if st else 'not registered'}"
        print(reason)
        pytest.skip(reason)
    result = _render(plane_scene("sun", (16, 12)), name, samples=2, outputs=("rgb", "depth"))
    assert undocumented_keys(result.meta) == []
    assert {"translate", "render", "total"} <= set(result.meta["timings"])
