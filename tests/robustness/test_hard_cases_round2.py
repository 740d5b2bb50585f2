"""Hard scenes, round two (issue 15): each renders right in every backend or warns, naming the cause and the
backend. Every case has a known answer (a reference render of the same scene made easy: at scale 1, with a
normal near clip, without the duplicate) and a benign variant that must render right WITHOUT a warning, so
a warning counts only where it is specific. Tiny images, few samples."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import blendify_core as bf

BACKENDS = ("pyrender", "mitsuba", "cycles")
RES = (32, 24)


@pytest.fixture(scope="module", params=BACKENDS)
def backend(request):
    status = bf.available_backends().get(request.param)
    if status is None or not status.available:
        reason = f"backend {request.param!r} unavailable: {getattr(status, 'reason', 'not registered')}"
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    return request.param


def _render(scene: bf.Scene, backend: str) -> tuple[bf.RenderResult, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bf.render(scene, backend=backend, samples=4, outputs=("rgb",))
    return result, [str(w.message) for w in caught]


def _coverage(result: bf.RenderResult) -> int:
    return int((result.rgba[..., 3] > 0.5).sum())


def _specific(messages: list[str], backend: str, cause: str) -> bool:
    return any(m.startswith(f"{backend}:") and cause in m for m in messages)


def _right_or_warned(backend, hard, reference, same, cause):
    """The hard scene renders like the reference, or a warning names the backend and the cause."""
    ref, _ = _render(reference, backend)
    got, messages = _render(hard, backend)
    assert np.all(np.isfinite(got.rgba))
    if not same(got, ref):
        assert _specific(messages, backend, cause), f"{backend}: wrong picture without a warning ({messages})"
    return got, messages


def _benign(backend, scene, reference, same, cause):
    ref, _ = _render(reference, backend)
    got, messages = _render(scene, backend)
    assert same(got, ref), f"{backend}: the benign variant renders wrong"
    assert not _specific(messages, backend, cause), f"{backend}: a warning for the benign variant: {messages}"


def _same_silhouette(a, b, tol=3):
    return abs(_coverage(a) - _coverage(b)) <= tol and _coverage(b) > 0


def _scaled(k: float, near: float | None = None) -> bf.Scene:
    s = bf.Scene()
    s.set_perspective_camera(
        RES, fov_x=0.8, translation=(0, 0, 4 * k), near=0.1 * k if near is None else near, far=100 * k
    )
    s.lights.add_sun(5.0, rotation_mode="look_at", rotation=(0, 0, -1))
    s.renderables.add_sphere_nurbs(0.5 * k, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    return s


def test_scene_scaled_beyond_float_range(backend):
    """The reference scene scaled by 1e15 (clip range too): Cycles and Mitsuba (float32) render nothing and
    warn; scaled by 1e12 (benign) it renders like scale 1, without a warning."""
    _benign(backend, _scaled(1e12), _scaled(1.0), _same_silhouette, "from the camera")
    _right_or_warned(backend, _scaled(1e15), _scaled(1.0), _same_silhouette, "from the camera")


def test_clip_range_the_engine_cannot_represent(backend):
    """near = 1e-30 m (far 100 m): pyrender's depth buffer and Mitsuba lose the sphere and warn; near = 1e-3 m
    (benign) renders like near = 0.1 m without a warning."""
    _benign(backend, _scaled(1.0, near=1e-3), _scaled(1.0), _same_silhouette, "near")
    _right_or_warned(backend, _scaled(1.0, near=1e-30), _scaled(1.0), _same_silhouette, "near")


def _quads(offset: float | None) -> bf.Scene:
    s = bf.Scene()
    s.set_perspective_camera(RES, fov_x=0.8, translation=(0, 0, 4))
    s.lights.add_point(200.0, translation=(1, 2, 4))
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    s.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.8, 0.8)), tag="a")
    if offset is not None:
        s.renderables.add_mesh(
            v + [0, 0, -offset], [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.8, 0.8)), tag="b"
        )
    return s


def _same_brightness(a, b):
    hit = (a.rgba[..., 3] > 0.5) & (b.rgba[..., 3] > 0.5)
    ma, mb = a.rgba[..., :3][hit].mean(), b.rgba[..., :3][hit].mean()
    return hit.sum() > 0 and abs(ma - mb) <= 0.1 * mb


def test_coincident_faces(backend):
    """Two coincident grey quads must look like one (z-fighting between equal colours is invisible); Cycles
    renders them dark (each shadows the other) and warns naming both. A second quad 5 cm behind (benign)
    renders like one quad, without a warning."""
    _benign(backend, _quads(0.05), _quads(None), _same_brightness, "same place")
    got, messages = _right_or_warned(backend, _quads(0.0), _quads(None), _same_brightness, "same place")
    if _specific(messages, backend, "same place"):
        assert "'a' and 'b'" in next(m for m in messages if "same place" in m)


def _box(camera_inside: bool) -> bf.Scene:
    s = bf.Scene()
    s.set_perspective_camera(RES, fov_x=0.8, translation=(0, 0, 0 if camera_inside else 8))
    s.renderables.add_cube_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="box")
    s.lights.add_sun(5.0, rotation_mode="look_at", rotation=(0, 0, -1))
    return s


def test_camera_inside_a_closed_box_is_dark(backend):
    """Known answer: the sun outside a closed box cannot light its inside: every pixel hits the box and is
    black. The benign variant (camera outside) sees the lit box."""
    inside, _ = _render(_box(True), backend)
    assert _coverage(inside) == RES[0] * RES[1]
    assert inside.rgba[..., :3].max() < 1e-3, f"{backend}: the inside of a closed box is lit"
    outside, messages = _render(_box(False), backend)
    assert outside.rgba[..., :3].max() > 0.05 and not [m for m in messages if m.startswith(f"{backend}:")]


def test_numeric_limit_warnings_name_the_backend_without_rendering():
    """The core's check alone (no engine): which backend warns for which scene, from its declared limits."""
    from blendify_core.pipeline.render import coincident_faces, numeric_limit_warnings

    class Fake(bf.Backend):
        name = "fake"
        numeric_limits = {"max_distance": 1e14, "max_clip_ratio": 1e8, "min_near": 1e-18, "coincident_faces": 1.0}

        def translate(self, scene, settings):  # pragma: no cover - never rendered
            raise NotImplementedError

        def render(self, native, settings):  # pragma: no cover - never rendered
            raise NotImplementedError

    fake = Fake()
    assert numeric_limit_warnings(_scaled(1.0), fake, _scaled(1.0).bounds()) == []
    far = _scaled(1e15)
    (w,) = numeric_limit_warnings(far, fake, far.bounds())
    assert w.startswith("fake: geometry 4.5e+15 m from the camera")
    near = _scaled(1.0, near=1e-30)
    assert [m.split(":")[0] for m in numeric_limit_warnings(near, fake, near.bounds())] == ["fake", "fake"]
    assert coincident_faces(_quads(0.0)) == [("a", "b")] and coincident_faces(_quads(0.05)) == []
    rotated = _quads(None)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    rotated.renderables.add_mesh(v[[2, 3, 0, 1]], [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    assert len(coincident_faces(rotated)) == 1  # the same quad given from another corner


def _zoom(fov: float, distance: float) -> bf.Scene:
    s = bf.Scene()
    s.set_perspective_camera((64, 48), fov_x=fov, translation=(0, 0, distance), near=distance * 0.5, far=distance * 2)
    s.lights.add_sun(5.0, rotation_mode="look_at", rotation=(0, 0, -1))
    s.renderables.add_sphere_nurbs(0.05, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    return s


def test_small_object_at_extreme_zoom(backend):
    """A 0.05 m sphere 1e6 m away through fov 1e-7 rad covers what it covers 100 m away through fov 1e-3 rad
    (the same picture: ~2750 of 3072 pixels); the benign variant is the 100 m one itself (no warning)."""

    def same(a, b):
        return abs(_coverage(a) - _coverage(b)) <= 0.02 * _coverage(b) and _coverage(b) > 2000

    _benign(backend, _zoom(1e-3, 100.0), _zoom(1e-3, 100.0), same, "from the camera")
    _right_or_warned(backend, _zoom(1e-7, 1e6), _zoom(1e-3, 100.0), same, "zoom")


def _ramp(alpha_bottom: float) -> bf.Scene:
    s = bf.Scene()
    s.set_perspective_camera(RES, fov_x=0.8, translation=(0, 0, 4))
    s.lights.add_point(200.0, translation=(1, 2, 4))
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    c = np.array([[1, 0, 0, alpha_bottom], [1, 0, 0, alpha_bottom], [1, 0, 0, 1], [1, 0, 0, 1]], float)
    s.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.VertexColors(c), tag="quad")
    return s


def test_vertex_colours_with_alpha_zero(backend):
    """Known answer: vertex alpha 0 at the bottom edge and 1 at the top is a linear ramp of coverage (alpha
    is never colour-managed): the quad's mean alpha is 1/2 and its rows fall monotonically from top to
    bottom. Benign: alpha 1 everywhere covers the quad fully. Neither warns."""
    full, messages = _render(_ramp(1.0), backend)
    quad = full.rgba[..., 3] > 0.5
    assert quad.sum() > 100 and np.all(full.rgba[..., 3][quad] > 0.99)
    assert not [m for m in messages if m.startswith(f"{backend}:")]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ramp = bf.render(_ramp(0.0), backend=backend, samples=64, outputs=("rgb",))
    alpha = ramp.rgba[..., 3]
    assert abs(alpha[quad].mean() - 0.5) < 0.05, f"{backend}: mean alpha {alpha[quad].mean():.3f}"
    rows = np.array([alpha[y][quad[y]].mean() for y in range(alpha.shape[0]) if quad[y].sum() > 4])
    assert np.all(np.diff(rows) < 0.05) and rows[0] > 0.8 and rows[-1] < 0.2, rows.round(2)
    assert not [str(w.message) for w in caught if str(w.message).startswith(f"{backend}:")]
