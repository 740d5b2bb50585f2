"""A fake backend for the core tests, registered through the public registry (see conftest.py).

The fake "renders" analytically with numpy: for every pixel centre it intersects the camera ray with
the renderables' bounding spheres, so outputs have correct shapes, dtypes and conventions
(premultiplied rgba, +inf background depth, -1 background instance) and respond to the camera
exactly. ``pattern="coords"`` writes the normalised camera coordinates (x/z, y/z) of each pixel's ray
into rgba[..., :2] so a test can see where the core's lens-distortion remap sampled; ``pattern="blobs"``
draws Gaussian blobs at the projections of the renderables' centres.

(A uniquely named module rather than conftest.py, so ``from core_fake_backend import FakeBackend``
never resolves to another folder's conftest.)
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

import blendify_core as bf
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import BackendStatus


class FakeBackend(Backend):
    name = "fake"
    engine = None
    # tests patch these class attributes (restored by the fixture)
    overrides: ClassVar[dict[str, Capability]] = {}
    available: ClassVar[bool] = True
    instances: ClassVar[list[FakeBackend]] = []
    blob_sigma: ClassVar[float] = 2.0  # pixels, pattern="blobs"

    def __init__(self, pattern: str = "shade", **options: Any) -> None:
        super().__init__(**options)  # unknown options -> InvalidSceneError
        if not isinstance(pattern, str) or pattern not in ("shade", "coords", "blobs"):
            raise bf.InvalidSceneError(f"pattern: expected 'shade', 'coords' or 'blobs', got {pattern!r}")
        self.pattern = pattern
        self.translated: list[Any] = []
        self.rendered_settings: list[bf.RenderSettings] = []
        FakeBackend.instances.append(self)

    @classmethod
    def probe(cls) -> BackendStatus:
        if not cls.available:
            return BackendStatus(False, "fake engine switched off by the test", None)
        return BackendStatus(True, None, "1.2.3")

    @classmethod
    def engine_version(cls) -> str | None:
        return "1.2.3"

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        caps = {name: Capability("exact") for name in ALL_FEATURES}
        caps.update(cls.overrides)
        return caps

    def translate(self, scene: Any, settings: bf.RenderSettings) -> Any:
        self.translated.append(scene)
        return {"camera": scene.camera, "renderables": list(scene.renderables)}

    def render(self, native: Any, settings: bf.RenderSettings) -> RenderResult:
        self.rendered_settings.append(settings)
        cam = native["camera"]
        w, h = cam.width, cam.height
        origins, dirs = cam.pixel_rays()
        rgba = np.zeros((h * w, 4), np.float32)
        depth = np.full(h * w, np.inf, np.float32)
        normal = np.zeros((h * w, 3), np.float32)
        albedo = np.zeros((h * w, 3), np.float32)
        instance = np.full(h * w, -1, np.int32)
        if self.pattern == "coords":
            r, _ = cam.opencv_extrinsics()
            d_cv = dirs @ r.T
            rgba[:, 0] = d_cv[:, 0] / d_cv[:, 2]
            rgba[:, 1] = d_cv[:, 1] / d_cv[:, 2]
            rgba[:, 3] = 1.0
        elif self.pattern == "blobs":
            # Gaussian blobs at the projections of the renderables' centres (marker spheres)
            vv, uu = np.mgrid[0:h, 0:w]
            img = np.zeros((h, w), np.float64)
            for obj in native["renderables"]:
                uv, z = cam.project(obj.translation[None])
                if z[0] > 0:
                    img += np.exp(-((uu - uv[0, 0]) ** 2 + (vv - uv[0, 1]) ** 2) / (2 * self.blob_sigma**2))
            a = np.clip(img, 0, 1).ravel().astype(np.float32)
            rgba[:] = a[:, None]
        else:
            # spheres bounding each renderable, nearest hit wins
            best = np.full(h * w, np.inf)
            for i, obj in enumerate(native["renderables"]):
                lo, hi = obj.world_bounds()
                c, rad = (lo + hi) / 2, max(np.linalg.norm(hi - lo) / 2, 1e-6)
                oc = origins - c
                b = np.sum(oc * dirs, axis=1)
                disc = b * b - (np.sum(oc * oc, axis=1) - rad * rad)
                t = -b - np.sqrt(np.maximum(disc, 0))
                hit = (disc > 0) & (t > 0) & (t < best)
                best[hit] = t[hit]
                p = origins[hit] + t[hit, None] * dirs[hit]
                n = (p - c) / rad
                normal[hit] = n
                col = obj.colors_list[0]
                lin = col.linear_rgba if hasattr(col, "linear_rgba") and np.ndim(col.linear_rgba) == 1 else np.ones(4)
                albedo[hit] = lin[:3]
                rgba[hit, :3] = lin[:3] * max(0.0, float(n[:, 2].mean()) if len(n) else 0.0)
                rgba[hit, 3] = 1.0
                instance[hit] = i
                depth[hit] = (t[hit] * (dirs[hit] @ cam.viewdir)).astype(np.float32)
        out: dict[str, Any] = {}
        shape = (h, w)
        if settings.wants("rgb"):
            out["rgba"] = rgba.reshape(shape + (4,))
        if settings.wants("depth"):
            out["depth"] = depth.reshape(shape)
        if settings.wants("normal"):
            out["normal"] = normal.reshape(shape + (3,))
        if settings.wants("albedo"):
            out["albedo"] = albedo.reshape(shape + (3,))
        if settings.wants("instance"):
            out["instance"] = instance.reshape(shape)
        return RenderResult(**out, meta={"samples": settings.samples, "pattern": self.pattern})


def close_fake_instances() -> None:
    """Close the shared instances of fake backends only (real backends' warm instances stay)."""
    from blendify_core import registry as backend_mod

    with backend_mod._lock:
        keys = [k for k, inst in backend_mod._shared.items() if isinstance(inst, FakeBackend)]
        instances = [backend_mod._shared.pop(k) for k in keys]
    for inst in instances:
        inst.close()


class NoisyPathTracer(Backend):
    """A fake path tracer: a constant ``truth`` grey plus Gaussian noise drawn from the render's seed, with
    per-sample standard deviation ``sigma`` (so it falls as 1/sqrt(samples)). Subclasses set their name
    and the two constants."""

    name = "noisy-fake-pt"
    path_tracer = True
    truth = 0.5
    sigma = 0.5

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return {k: Capability("exact") for k in ALL_FEATURES}

    def translate(self, scene: Any, settings: Any) -> Any:
        return scene

    def render(self, native: Any, settings: Any) -> RenderResult:
        w, h = native.camera.resolution
        rng = np.random.default_rng(settings.seed)
        rgb = self.truth + rng.normal(size=(h, w, 3)) * self.sigma / np.sqrt(settings.samples)
        rgba = np.concatenate([rgb, np.ones((h, w, 1))], axis=-1).astype(np.float32)
        return RenderResult(rgba=rgba, meta={"samples": settings.samples, "seed": settings.seed})


class FlatPlane(Backend):
    """Analytic 'renders' of ``testing.depth_plane_scene``: the exact plane depth and a constant grey
    (0.25 times :meth:`gain`); a path tracer. Subclasses set ``name`` (and may override ``gain``)."""

    path_tracer = True

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return {k: Capability("exact") for k in ALL_FEATURES}

    def translate(self, scene: Any, settings: bf.RenderSettings) -> Any:
        return scene

    def gain(self, settings: bf.RenderSettings) -> float:
        return 1.0

    def render(self, native: Any, settings: bf.RenderSettings) -> RenderResult:
        from blendify_core.testing import expected_plane_depth

        d = expected_plane_depth(native).astype(np.float32)
        hit = np.isfinite(d)
        v = 0.25 * self.gain(settings)
        rgba = np.zeros(d.shape + (4,), np.float32)
        rgba[hit] = (v, v, v, 1.0)
        return RenderResult(rgba=rgba, depth=d if settings.wants("depth") else None, meta={})
