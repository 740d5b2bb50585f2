"""bf.render with fake backends registered through the public registry: backend choice and fallback,
capability checks, outputs, settings, options, warnings, resolution_percentage, lens distortion and
the metadata every result carries."""

from __future__ import annotations

import logging
import warnings

import numpy as np
import pytest
from core_fake_backend import FakeBackend, close_fake_instances

import blendify_core as bf
from blendify_core import registry as backend_mod
from blendify_core.errors import BackendUnavailableError, RenderError, UnsupportedFeatureError
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.distortion import distort_points, undistort_points
from blendify_core.registry import register_backend, unregister_backend

# ---------------------------------------------------------------------------------------------------
# backend choice
# ---------------------------------------------------------------------------------------------------


def _fake_named(name: str, available: bool = True) -> type[FakeBackend]:
    return type(f"Fake_{name}", (FakeBackend,), {"name": name, "available": available})


@pytest.fixture
def engines(fake_backend):
    """Fakes registered under the real backend names (run-time registrations shadow entry points)."""
    classes = {n: _fake_named(n) for n in ("cycles", "mitsuba", "pyrender")}
    # real backends' warm shared instances (from earlier test files) would shadow the fakes: set aside
    with backend_mod._lock:
        stashed = {k: backend_mod._shared.pop(k) for k in list(backend_mod._shared) if k[0] in classes}
    for n, cls in classes.items():
        register_backend(n, cls)
    fake_backend.available = False  # keep the generic fake out of the automatic choice
    try:
        yield classes
    finally:
        close_fake_instances()
        for n in classes:
            unregister_backend(n)
        with backend_mod._lock:
            backend_mod._shared.update(stashed)


@pytest.mark.parametrize(("quality", "expected"), [("preview", "pyrender"), ("draft", "cycles"), ("final", "cycles")])
def test_backend_none_picks_the_preferred_backend(engines, simple_scene, quality, expected):
    result = bf.render(simple_scene(), quality=quality)
    assert result.meta["backend"] == expected
    assert "backend_fallback" not in result.meta


def test_backend_none_falls_back_with_a_reason(engines, simple_scene, caplog):
    engines["cycles"].available = False
    with caplog.at_level(logging.INFO, logger="blendify_core"):
        result = bf.render(simple_scene(), quality="final")
    assert result.meta["backend"] == "mitsuba"
    assert result.meta["backend_fallback"] == ["cycles: fake engine switched off by the test"]
    assert "cycles" in caplog.text
    engines["mitsuba"].available = False
    assert bf.render(simple_scene(), quality="final").meta["backend"] == "pyrender"
    engines["pyrender"].available = False
    with pytest.raises(BackendUnavailableError, match="no backend is available") as info:
        bf.render(simple_scene(), quality="preview")
    for name in ("cycles", "mitsuba", "pyrender"):
        assert name in str(info.value)


def test_available_backends_reports_every_registered_backend(engines):
    engines["mitsuba"].available = False
    status = bf.available_backends()
    assert status["cycles"] == bf.BackendStatus(True, None, "1.2.3")
    assert status["mitsuba"].available is False and "switched off" in status["mitsuba"].reason
    assert {"cycles", "mitsuba", "pyrender", "fake"} <= set(bf.backend_names())
    with pytest.raises(BackendUnavailableError, match="switched off"):
        bf.get_backend("mitsuba")


def test_broken_third_party_backend_does_not_take_the_registry_down(fake_backend):
    register_backend("broken", "no_such_module_xyz:Backend")
    register_backend("notabackend", "json:dumps")
    try:
        status = bf.available_backends()
        assert status["broken"].available is False and "no_such_module_xyz" in status["broken"].reason
        assert (
            status["notabackend"].available is False and "not a blendify_core.Backend" in status["notabackend"].reason
        )
        with pytest.raises(BackendUnavailableError):
            bf.get_backend_class("broken")
    finally:
        unregister_backend("broken")
        unregister_backend("notabackend")


def test_shared_instances_are_reused_per_options(fake_backend, simple_scene):
    s = simple_scene()
    bf.render(s, backend="fake")
    bf.render(s, backend="fake", samples=3)
    assert len(FakeBackend.instances) == 1
    bf.render(s, backend="fake", pattern="coords")
    assert len(FakeBackend.instances) == 2
    with bf.get_backend("fake", pattern="coords") as inst:
        r = bf.render(s, backend=inst)
        assert r.meta["pattern"] == "coords"
    with pytest.raises(BackendUnavailableError, match="closed"):
        bf.render(s, backend=inst)


# ---------------------------------------------------------------------------------------------------
# capabilities
# ---------------------------------------------------------------------------------------------------


def test_unsupported_feature_names_feature_and_backend(fake_backend, simple_scene):
    fake_backend.overrides = {"primitive.sphere": Capability("unsupported", "no spheres here")}
    with pytest.raises(UnsupportedFeatureError) as info:
        bf.render(simple_scene(), backend="fake")
    err = info.value
    assert err.feature == "primitive.sphere" and err.backend == "fake"
    assert "primitive.sphere" in str(err) and "'fake'" in str(err) and "no spheres here" in str(err)
    assert "ball" in str(err)  # where it is used


def test_undeclared_feature_counts_as_unsupported(fake_backend, simple_scene):
    class Partial(FakeBackend):
        name = "partial"

        @classmethod
        def capabilities(cls):
            caps = super().capabilities()
            del caps["output.depth"]
            return caps

    register_backend("partial", Partial)
    try:
        bf.render(simple_scene(), backend="partial")  # rgb only: fine
        with pytest.raises(UnsupportedFeatureError, match="output.depth"):
            bf.render(simple_scene(), backend="partial", outputs=("rgb", "depth"))
    finally:
        unregister_backend("partial")


def test_approximations_are_listed_and_strict_raises(fake_backend, simple_scene):
    fake_backend.overrides = {
        "light.point": Capability("approximate", "as a tiny sphere light"),
        "light.spot": Capability("approximate", "unused by the scene"),
    }
    result = bf.render(simple_scene(), backend="fake")
    assert result.meta["approximations"] == ["light.point: as a tiny sphere light"]
    with pytest.raises(UnsupportedFeatureError, match="strict") as info:
        bf.render(simple_scene(), backend="fake", strict=True)
    assert info.value.feature == "light.point" and info.value.backend == "fake"
    fake_backend.overrides = {}
    assert bf.render(simple_scene(), backend="fake", strict=True).meta["approximations"] == []


def test_every_feature_name_is_checked(fake_backend):
    """A backend that supports nothing rejects every feature the every-feature scene uses."""
    from blendify_core.pipeline.capabilities import scene_features
    from blendify_core.testing import every_feature_scene

    s = every_feature_scene()
    used = scene_features(s, ("rgb", "depth", "normal", "albedo", "instance"))
    assert set(used) <= set(ALL_FEATURES)
    assert len(used) >= 35
    for feature in used:
        fake_backend.overrides = {feature: Capability("unsupported", "test")}
        with pytest.raises(UnsupportedFeatureError) as info:
            bf.render(s, backend="fake", outputs=("rgb", "depth", "normal", "albedo", "instance"))
        assert info.value.feature == feature


# ---------------------------------------------------------------------------------------------------
# outputs, settings, options, warnings
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "outputs",
    [("rgb",), ("depth",), ("normal", "albedo"), ("instance", "rgb"), ("rgb", "depth", "normal", "albedo", "instance")],
)
def test_only_requested_outputs_are_returned(fake_backend, simple_scene, outputs):
    result = bf.render(simple_scene((32, 24)), backend="fake", outputs=outputs)
    expect = {"rgb": ("rgba", (24, 32, 4)), "depth": ("depth", (24, 32)), "normal": ("normal", (24, 32, 3))}
    expect.update({"albedo": ("albedo", (24, 32, 3)), "instance": ("instance", (24, 32))})
    for name, (attr, shape) in expect.items():
        data = getattr(result, attr)
        if name in outputs:
            assert data is not None and data.shape == shape
            assert data.dtype == (np.int32 if name == "instance" else np.float32)
        else:
            assert data is None, f"{name} was not requested"
    assert result.resolution == (32, 24)
    assert result.instance_tags == ["ball"]


def test_conventions_of_the_fake_outputs(fake_backend, simple_scene):
    r = bf.render(simple_scene((33, 25)), backend="fake", outputs=("rgb", "depth", "instance", "normal"))
    centre = (12, 16)
    assert r.instance[centre] == 0 and r.instance[0, 0] == -1
    # camera at z=4; the fake intersects the sphere bounding the ball's box (radius sqrt(3) / 2)
    assert np.isclose(r.depth[centre], 4 - np.sqrt(3) / 2, atol=1e-5)
    assert np.isinf(r.depth[0, 0]) and r.depth[0, 0] > 0
    assert np.all(r.normal[0, 0] == 0)
    assert np.array_equal(r.mask, np.isfinite(r.depth))


def test_backend_returning_wrong_outputs_is_a_render_error(fake_backend, simple_scene):
    class Sloppy(FakeBackend):
        name = "sloppy"
        mode = "missing"

        def render(self, native, settings):
            result = super().render(native, settings)
            if self.mode == "missing":
                result.depth = None
            elif self.mode == "shape":
                result.depth = result.depth[:-1]
            else:  # returns more than asked, in float64
                result.normal = np.zeros(result.depth.shape + (3,))
                result.depth = result.depth.astype(np.float64)
            return result

    register_backend("sloppy", Sloppy)
    try:
        with pytest.raises(RenderError, match="no 'depth' output"):
            bf.render(simple_scene(), backend="sloppy", outputs=("depth",))
        Sloppy.mode = "shape"
        close_fake_instances()
        with pytest.raises(RenderError, match="shape"):
            bf.render(simple_scene(), backend="sloppy", outputs=("depth",))
        Sloppy.mode = "extra"
        close_fake_instances()
        r = bf.render(simple_scene(), backend="sloppy", outputs=("depth",))
        assert r.normal is None and r.depth.dtype == np.float32
    finally:
        unregister_backend("sloppy")


def test_settings_overrides_via_keyword_arguments(fake_backend, simple_scene):
    r = bf.render(
        simple_scene(),
        backend="fake",
        quality="draft",
        samples=5,
        seed=7,
        threads=2,
        denoise=False,
        max_bounces=3,
        pixel_filter="gaussian",
        clamp_indirect=10.0,
        outputs="depth",
    )
    used = FakeBackend.instances[-1].rendered_settings[-1]
    assert (used.quality, used.samples, used.seed, used.threads) == ("draft", 5, 7, 2)
    assert (used.denoise, used.max_bounces, used.pixel_filter, used.clamp_indirect) == (False, 3, "gaussian", 10.0)
    assert used.outputs == ("depth",)
    assert r.meta["settings"] == used.to_dict()
    # the preset fills what was not given
    bf.render(simple_scene(), backend="fake", quality="preview")
    preview = FakeBackend.instances[-1].rendered_settings[-1]
    assert (preview.samples, preview.denoise, preview.max_bounces) == (8, True, 4)


def test_backend_options_reach_the_backend_and_unknown_ones_are_rejected(fake_backend, simple_scene):
    r = bf.render(simple_scene(), backend="fake", pattern="coords")
    assert r.meta["pattern"] == "coords"
    with pytest.raises(bf.InvalidSceneError, match="variant"):
        bf.render(simple_scene(), backend="fake", variant="scalar_rgb")
    with pytest.raises(bf.InvalidSceneError, match="pattern"):
        bf.render(simple_scene(), backend="fake", pattern="stripes")
    with bf.get_backend("fake") as inst, pytest.raises(bf.InvalidSceneError, match="pattern"):
        bf.render(simple_scene(), backend=inst, pattern="coords")


def test_no_lights_warning(fake_backend, simple_scene):
    dark = simple_scene(lights=False)
    with pytest.warns(UserWarning, match="no lights"):
        bf.render(dark, backend="fake")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bf.render(dark, backend="fake", outputs=("depth", "instance"))  # no colour: nothing to warn about
        lit_bg = simple_scene(lights=False)
        lit_bg.lights.set_background_light(0.5)
        bf.render(lit_bg, backend="fake")
        glowing = simple_scene(lights=False)
        glowing.renderables["ball"].update_material(
            bf.PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=1)
        )
        bf.render(glowing, backend="fake")


def test_resolution_percentage(fake_backend):
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), tag="ball")
    s.lights.add_sun()
    k = np.array([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]])
    s.set_perspective_camera((64, 48), K=k, translation=(0, 0, 4), resolution_percentage=50)
    r = bf.render(s, backend="fake", outputs=("rgb", "depth"))
    assert r.rgba.shape == (24, 32, 4) and r.depth.shape == (24, 32)
    seen = FakeBackend.instances[-1].translated[-1].camera
    assert (seen.width, seen.height) == (32, 24)
    assert np.isclose(seen.fx, 30.0) and np.isclose(seen.cx, 15.5) and np.isclose(seen.cy, 11.5)
    assert s.camera.width == 64  # the user's camera is untouched
    full = bf.render(s.with_camera(s.camera._scaled(1.0)), backend="fake", outputs=("depth",))
    assert full.depth.shape == (48, 64)


# ---------------------------------------------------------------------------------------------------
# lens distortion
# ---------------------------------------------------------------------------------------------------


def opencv_distort(x: np.ndarray, y: np.ndarray, k1, k2, p1, p2, k3):
    """OpenCV's distortion model written from its documentation (independent of blendify_core)."""
    r2 = x**2 + y**2
    radial = 1.0 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x**2)
    yd = y * radial + p1 * (r2 + 2.0 * y**2) + 2.0 * p2 * x * y
    return xd, yd


DISTORTIONS = {
    "barrel": (-0.25, 0.08, 0.0, 0.0, 0.0),
    "pincushion": (0.15, 0.02, 0.0, 0.0, -0.01),
    "tangential": (-0.1, 0.01, 0.002, -0.003, 0.0),
}


@pytest.mark.parametrize("name", sorted(DISTORTIONS))
def test_distortion_functions_match_an_independent_implementation(name, rng):
    d = np.array(DISTORTIONS[name])
    xy = rng.uniform(-0.6, 0.6, size=(500, 2))
    ours = distort_points(xy, d)
    ref = np.stack(opencv_distort(xy[:, 0], xy[:, 1], *d), axis=1)
    assert np.max(np.abs(ours - ref)) < 1e-14
    back = undistort_points(ours, d)
    assert np.max(np.abs(back - xy)) < 1e-9


def _distorted_scene(d, resolution=(80, 60), k=None):
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), tag="ball")
    s.lights.add_sun()
    k = np.array([[70.0, 0, 41.3], [0, 64.0, 28.8], [0, 0, 1]]) if k is None else k
    s.set_camera_from_opencv(k, np.eye(3), (0.1, -0.2, 5.0), resolution, distortion=d)
    return s


@pytest.mark.parametrize("name", sorted(DISTORTIONS))
def test_distortion_remap_samples_where_opencv_says(fake_backend, name):
    """The fake writes each pixel's undistorted normalised ray coordinates (x, y); after the core's remap,
    output pixel (u, v) must hold the (x, y) whose OpenCV distortion lands on (u, v)."""
    d = DISTORTIONS[name]
    s = _distorted_scene(d)
    cam = s.camera
    r = bf.render(s, backend="fake", pattern="coords", outputs=("rgb", "depth"))
    assert r.rgba.shape == (60, 80, 4) and r.depth.shape == (60, 80)
    render_cam = FakeBackend.instances[-1].translated[-1].camera
    assert render_cam.distortion is None, "backends must get a pinhole camera"
    assert render_cam.width >= cam.width and render_cam.height >= cam.height
    assert np.isclose(render_cam.fx, cam.fx) and np.isclose(render_cam.fy, cam.fy)
    assert np.array_equal(render_cam.quaternion, cam.quaternion)
    x, y = r.rgba[..., 0].astype(np.float64), r.rgba[..., 1].astype(np.float64)
    xd, yd = opencv_distort(x, y, *d)
    u = cam.fx * xd + cam.cx
    v = cam.fy * yd + cam.cy
    vv, uu = np.mgrid[0 : cam.height, 0 : cam.width]
    err = np.hypot(u - uu, v - vv)
    assert err.max() < 0.05, f"max error {err.max():.4f} px"
    assert "distortion" in r.meta["timings"]


def _centroid(w, uu, vv):
    return np.array([np.sum(w * uu), np.sum(w * vv)]) / np.sum(w)


def test_distorted_markers_land_where_opencv_says(fake_backend):
    """Gaussian blobs at projected sphere centres, remapped by the core: each blob's alpha-weighted
    centroid matches (within 0.05 px) the centroid of the ideal distorted blob, evaluated analytically
    through OpenCV's model, and lies within 0.1 px of the distorted projection of its centre (the rest
    is the centroid estimator's own bias under a non-linear warp). Blobs are 2 px wide: the remap's
    sample positions are exact (see the test above, ~1e-6 px) but bilinear resampling without a
    prefilter aliases sharper blobs by ~0.05 px where the warp compresses the image."""
    d = (-0.2, 0.05, 0.001, -0.002, 0.0)
    s = bf.Scene()
    f, c = 120.0, np.array([79.5, 59.5])
    s.set_camera_from_opencv(np.array([[f, 0, c[0]], [0, f, c[1]], [0, 0, 1]]), np.eye(3), (0, 0, 0), (160, 120), d)
    pixels = np.array([[20.0, 18.0], [140.0, 22.0], [25.0, 100.0], [135.0, 98.0], [80.0, 60.0], [50.0, 70.0]])
    xy = undistort_points((pixels - c) / f, np.array(d))  # normalised coordinates that distort onto `pixels`
    assert np.max(np.abs(np.stack(opencv_distort(xy[:, 0], xy[:, 1], *d), 1) * f + c - pixels)) < 1e-6
    depth = 5.0
    for i, (x, y) in enumerate(xy):
        s.renderables.add_sphere_nurbs(
            0.01,
            bf.DiffuseMaterial(),
            bf.UniformColors((1, 1, 1)),
            translation=(x * depth, y * depth, depth),
            tag=f"m{i}",
        )
    s.lights.add_sun()
    r = bf.render(s, backend="fake", pattern="blobs")
    alpha = r.rgba[..., 3].astype(np.float64)
    vv, uu = np.mgrid[0:120, 0:160]
    # ideal distorted image: each output pixel looks along its undistorted ray
    und = undistort_points(np.stack([(uu.ravel() - c[0]) / f, (vv.ravel() - c[1]) / f], 1), np.array(d))
    pin = (und * f + c).reshape(120, 160, 2)
    sigma = FakeBackend.blob_sigma
    for p, (x, y) in zip(pixels, xy):
        centre = np.array([x, y]) * f + c
        ideal = np.exp(-np.sum((pin - centre) ** 2, axis=-1) / (2 * sigma**2))
        win = (np.abs(uu - p[0]) <= 9) & (np.abs(vv - p[1]) <= 9)

        got, want = _centroid(alpha * win, uu, vv), _centroid(ideal * win, uu, vv)
        assert np.hypot(*(got - want)) < 0.05, f"marker at {p}: remapped centroid {got}, ideal {want}"
        assert np.hypot(*(got - p)) < 0.1, f"marker at {p} landed at {got}"


@pytest.mark.parametrize(
    "d",
    [(-1.5, 0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.5, 0.5, 0.0), (-0.8, 0.0, 0.0, 0.0, 0.0)],
    ids=["folding-barrel", "diverging-tangential", "strong-barrel"],
)
def test_uninvertible_distortion_is_refused(fake_backend, d):
    s = _distorted_scene(d)
    with pytest.raises(bf.InvalidSceneError, match="distortion"):
        bf.render(s, backend="fake")


# ---------------------------------------------------------------------------------------------------
# metadata
# ---------------------------------------------------------------------------------------------------


def test_meta_contents(fake_backend, simple_scene):
    s = simple_scene()
    r = bf.render(s, backend="fake", quality="draft", samples=4, outputs=("rgb", "depth"))
    meta = r.meta
    assert meta["backend"] == "fake" and meta["engine_version"] == "1.2.3"
    assert meta["scene_fingerprint"] == s.fingerprint()
    assert meta["settings"]["quality"] == "draft" and meta["settings"]["samples"] == 4
    assert meta["settings"]["outputs"] == ["rgb", "depth"]
    assert meta["samples"] == 4
    assert set(meta["effects"]) >= {"shadows", "glossy", "reasons"}
    assert meta["effects"] == bf.analyse_effects(s).to_dict()
    assert meta["approximations"] == []
    t = meta["timings"]
    assert {"translate", "render", "total"} <= set(t)
    assert all(v >= 0 for v in t.values()) and t["total"] >= t["translate"] + t["render"]
    assert r.provenance()["scene_fingerprint"] == s.fingerprint()
    import json

    json.dumps(meta)  # metadata is plain data (it goes into PNG/EXR headers)


def test_engine_errors_propagate_unchanged(fake_backend, simple_scene):
    class Failing(FakeBackend):
        name = "failing"

        def render(self, native, settings):
            raise RenderError("failing: engine said 'out of memory'")

    register_backend("failing", Failing)
    try:
        with pytest.raises(RenderError, match="out of memory"):
            bf.render(simple_scene(), backend="failing")
    finally:
        unregister_backend("failing")


def test_registry_cleanup(fake_backend):
    assert "fake" in backend_mod._registered


def test_distortion_with_resolution_percentage(fake_backend):
    d = DISTORTIONS["tangential"]
    s = _distorted_scene(d, resolution=(80, 60))
    s.camera.resolution_percentage = 50
    r = bf.render(s, backend="fake", pattern="coords", outputs=("rgb", "instance"))
    assert r.rgba.shape == (30, 40, 4) and r.instance.shape == (30, 40) and r.instance.dtype == np.int32
    small = s.camera._scaled(0.5)
    x, y = r.rgba[..., 0].astype(np.float64), r.rgba[..., 1].astype(np.float64)
    xd, yd = opencv_distort(x, y, *d)
    vv, uu = np.mgrid[0:30, 0:40]
    err = np.hypot(small.fx * xd + small.cx - uu, small.fy * yd + small.cy - vv)
    assert err.max() < 0.05


def test_distortion_remap_keeps_output_conventions(fake_backend):
    s = _distorted_scene(DISTORTIONS["barrel"])
    s.renderables["ball"].update_colors(bf.UniformColors((0.5, 0.25, 1.0)))
    outputs = ("rgb", "depth", "normal", "albedo", "instance")
    r = bf.render(s, backend="fake", outputs=outputs)
    n = np.linalg.norm(r.normal, axis=-1)
    hit = r.instance >= 0
    assert hit.any() and (~hit).any()
    assert np.allclose(n[hit], 1.0, atol=1e-5)  # renormalised after interpolation (edges excepted below)
    assert np.all(np.isinf(r.depth[~hit])) and np.all(np.isfinite(r.depth[hit]))
    assert set(np.unique(r.instance)) <= {-1, 0}
    interior = hit.copy()
    for _ in range(2):  # away from the silhouette, where bilinear (albedo) and nearest (instance) differ
        interior &= (
            np.roll(interior, 1, 0) & np.roll(interior, -1, 0) & np.roll(interior, 1, 1) & np.roll(interior, -1, 1)
        )
    assert interior.sum() > 20
    assert np.allclose(r.albedo[interior], bf.UniformColors((0.5, 0.25, 1.0)).linear_rgba[:3], atol=1e-6)
    assert r.rgba.dtype == np.float32 and r.depth.dtype == np.float32 and r.instance.dtype == np.int32
