"""Rendering a translated scene into a RenderResult: the colour image with ``mi.render`` (composited for
coverage alpha under a sky, shadow catchers emulated, non-square pixels resampled) and the geometric
outputs (depth, normal, albedo, instance) from our own rays through the pixel centres (exact, not
filtered).

Timings of the backend's own (``meta["timings"]``, seconds, besides the core's ``translate`` and
``render``): ``render_rgb`` (every colour pass and its post-processing) and ``ray_cast`` (the geometric
outputs).

Mitsuba and Dr.Jit are imported inside the functions that use them; callers hold the session's engine
(:meth:`blendify_mitsuba.session.MitsubaSession.engine`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from blendify_core.errors import BlendifyError, InvalidSceneError, RenderError
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings, settings_bias

from .aniso import resample_rows
from .session import MitsubaNative, MitsubaSession
from .translate import ShapeInfo

__all__ = ["render_native", "render_rgba", "seen_lights", "cast_outputs", "catch_shadows"]

_MAX_PASS_THROUGH = 8  # light shapes (null BSDF) a geometric ray may pass through


def render_native(
    native: MitsubaNative, settings: RenderSettings, session: MitsubaSession, backend: str, engine_version: str | None
) -> RenderResult:
    """Render ``native`` (from :meth:`MitsubaSession.translate`) with ``settings``: the requested outputs and
    the meta data of the render."""
    if not isinstance(native, MitsubaNative):
        raise InvalidSceneError(f"native: expected a MitsubaNative from translate(), got {type(native).__name__}")
    timings: dict[str, float] = {}
    out: dict[str, Any] = {}
    with session.engine():
        if settings.threads is not None:
            import drjit as dr

            dr.set_thread_count(int(settings.threads))
        try:
            if settings.wants("rgb"):
                t0 = time.perf_counter()
                rgba = _film(native, native.scene, settings)
                if native.catcher_scene is not None:
                    rgba = catch_shadows(native, rgba, settings)
                if native.aniso is not None:
                    cam = native.camera
                    rgba = resample_rows(rgba, cam.width, cam.height, native.aniso.k, native.aniso.row_scale)
                if not settings.transparent_background:
                    rgba[..., 3] = 1.0
                out["rgba"] = rgba
                timings["render_rgb"] = time.perf_counter() - t0
            geo = tuple(o for o in ("depth", "normal", "albedo", "instance") if settings.wants(o))
            geo = tuple(o for o in geo if o not in out)
            if geo:
                t0 = time.perf_counter()
                out.update(
                    cast_outputs(
                        native.scene,
                        native.camera,
                        native.shapes,
                        geo,
                        vectorised=not native.variant.startswith("scalar"),
                        parallel=native.parallel_rays,
                    )
                )
                timings["ray_cast"] = time.perf_counter() - t0
        except BlendifyError:
            raise
        except Exception as exc:
            raise RenderError(f"mitsuba: rendering failed: {type(exc).__name__}: {exc}") from exc
    choice = session.variant_choice
    meta = {
        "backend": backend,
        "engine_version": engine_version,
        "variant": native.variant,
        "variant_reason": choice.reason,
        "libllvm": choice.libllvm,
        "integrator": native.integrator["type"],
        "max_depth": native.integrator["max_depth"],
        "hide_emitters": native.integrator["hide_emitters"],
        "spp": settings.samples,
        "rendered_spp": _sampler_count(native),
        "samples": settings.samples,
        "sampler": session.sampler,
        "seed": settings.seed,
        "pixel_filter": settings.pixel_filter,
        # of the biased settings Mitsuba applies only caustics=False (blendify_path): clamps, Filter Glossy and
        # per-kind bounce limits are in meta["approximations"] (Backend.unapplied_settings), the denoiser and
        # adaptive stop in "notes"
        "bias": settings_bias(settings, only=("caustics",)),
        "alpha_compositing": native.coverage_scene is not None,
        "lights_removed": bool(native.light_shapes),
        "shadow_catcher_emulated": native.catcher_scene is not None,
        "analytic_spheres": native.n_analytic_spheres,
        "translate_cached": native.translate_cached,
        "timings": timings,
    }
    if native.effects is not None:
        meta["effects"] = native.effects.to_dict()
    if native.ignored:
        meta["ignored"] = sorted(set(native.ignored))
    if native.approximations:
        meta["approximations"] = sorted(set(native.approximations))
    if settings.denoise:
        meta.setdefault("notes", []).append("denoise requested: Mitsuba's CPU build has no denoiser (not applied)")
    if settings.adaptive or settings.time_limit or settings.target_error:
        meta.setdefault("notes", []).append(
            "adaptive / time_limit / target_error are not supported by Mitsuba: fixed spp rendered"
        )
    if settings.pixel_filter == "blackman_harris":
        meta.setdefault("notes", []).append(
            "pixel_filter 'blackman_harris': Mitsuba has none; a Gaussian of the same standard deviation is used"
        )
    return RenderResult(
        rgba=out.get("rgba"),
        depth=out.get("depth"),
        normal=out.get("normal"),
        albedo=out.get("albedo"),
        instance=out.get("instance"),
        instance_tags=[],
        meta=meta,
    )


def _sampler_count(native: MitsubaNative) -> int:
    """Samples per pixel the loaded sensor really takes (stratified samplers round the request up)."""
    try:
        return int(native.scene.sensors()[0].sampler().sample_count())
    except Exception:  # a scene without a sensor (never built by this backend): report the plan
        return int(native.spp)


def render_rgba(scene: Any, spp: int, seed: int) -> np.ndarray:
    """(H, W, 4) float32 linear premultiplied RGBA."""
    import mitsuba as mi

    img = np.array(mi.render(scene, spp=int(spp), seed=int(seed)), dtype=np.float32)
    if img.ndim == 3 and img.shape[2] == 3:
        img = np.concatenate([img, np.ones(img.shape[:2] + (1,), np.float32)], axis=2)
    return img[..., :4]


def _sky(native: MitsubaNative, settings: RenderSettings) -> np.ndarray:
    """What the sky alone gives each pixel: a constant sky's radiance (3,), else the sky-only render (H, W, 3)."""
    if native.sky_radiance is not None:
        return np.asarray(native.sky_radiance, np.float32)
    return render_rgba(native.sky_scene, native.spp, settings.seed)[..., :3]


def seen_lights(scene: Any, keys: list[str], spp: int, seed: int) -> np.ndarray:
    """(H, W, 3) float32: the emission of the light shapes ``keys`` (ids of point-light spheres and area-light
    surfaces) where camera rays meet them first, as the render of ``scene`` with ``spp`` and ``seed`` counts it.

    Cycles' lights are not seen by camera rays. Mitsuba's ``hide_emitters`` would hide them, but in Mitsuba
    3.9 camera rays then pass through every emitter, emissive surfaces and the sky included; where the
    integrator keeps emitters visible, the render subtracts this instead. It is the difference of two
    one-bounce renders (``path``, max_depth 1: emission at the first hit only) of the same scene, with these
    emitters' radiance as it is and set to 0: the same seed gives the same camera samples, so everything but
    the light shapes' emission cancels sample by sample (no noise added). Not removed: a light seen through
    another light's shape or through a partly transparent (alpha) surface."""
    import mitsuba as mi

    one = mi.load_dict({"type": "path", "max_depth": 1, "hide_emitters": False})
    wanted = set(keys)
    params = [mi.traverse(s.emitter()) for s in scene.shapes() if s.id() in wanted and s.emitter() is not None]
    if not params:
        return np.zeros((1, 1, 3), np.float32)
    lit = np.array(mi.render(scene, spp=int(spp), seed=int(seed), integrator=one), dtype=np.float32)[..., :3]
    saved = [type(v)(v) for v in (p["radiance.value"] for p in params)]  # copies, not views
    try:
        for p, value in zip(params, saved):
            p["radiance.value"] = value * 0.0
            p.update()
        dark = np.array(mi.render(scene, spp=int(spp), seed=int(seed), integrator=one), dtype=np.float32)[..., :3]
    finally:
        for p, value in zip(params, saved):
            p["radiance.value"] = value
            p.update()
    return np.maximum(lit - dark, 0.0)  # type: ignore[no-any-return]


#: a pixel whose centre sees the background is a catcher's edge when its coverage exceeds the catchers' alone
#: by at most this much (both renders draw the same camera rays: equal where only the catcher is covered)
_EDGE_COVERAGE_TOLERANCE = 1e-3


def _film(native: MitsubaNative, scene: Any, settings: RenderSettings) -> np.ndarray:
    """``scene`` (the scene, or the one without shadow catchers) rendered with the film's treatment: the light
    shapes the camera sees removed, the coverage alpha or the sky behind uncovered pixels as needed."""
    rgba = render_rgba(scene, native.spp, settings.seed)
    if native.light_shapes:
        seen = seen_lights(scene, native.light_shapes, native.spp, settings.seed)
        rgba[..., :3] = np.maximum(rgba[..., :3] - seen, 0.0)
    if native.coverage_scene is not None:
        # emissive surfaces + a sky: rendered with the sky visible; the coverage alpha comes
        # from a one-bounce pass of the shapes, the sky behind partly covered pixels is removed
        alpha = render_rgba(native.coverage_scene, native.spp, settings.seed)[..., 3]
        rgba[..., :3] -= (1.0 - alpha)[..., None] * _sky(native, settings)
        rgba[..., :3] = np.maximum(rgba[..., :3], 0.0)
        rgba[..., 3] = alpha
    elif native.sky_scene is not None:
        # an opaque film whose emitters were hidden from the camera (the light shapes; the sky too,
        # in Mitsuba 3.9): the sky behind the pixels' uncovered part is added back
        rgba[..., :3] += (1.0 - rgba[..., 3])[..., None] * _sky(native, settings)
    return rgba


def catch_shadows(native: MitsubaNative, rgba: np.ndarray, settings: RenderSettings) -> np.ndarray:
    """Shadow-catcher emulation: where a pixel centre sees a catcher, the pixel becomes black with
    alpha = (1 - shadowed / unshadowed radiance) x coverage; the unshadowed radiance comes from a
    render of the catchers alone (same seed and samples). The other pixels come from a render without the
    catchers: in Cycles a catcher neither lights nor shades the other objects (measured on
    ``testing.pointcloud_catcher_scene``: the white catcher's bounce made the bunny 14-25 % brighter than in
    Cycles; without it the object pixels agree to a relative MSE of 4e-4)."""
    free = render_rgba(native.catcher_scene, native.spp, settings.seed)
    # the catcher scene holds the same lights and integrator: the same treatment of what the camera sees of them
    if native.light_shapes:
        seen = seen_lights(native.catcher_scene, native.light_shapes, native.spp, settings.seed)
        free[..., :3] = np.maximum(free[..., :3] - seen, 0.0)
    elif native.sky_scene is not None and native.coverage_scene is None:
        free[..., :3] += (1.0 - free[..., 3])[..., None] * _sky(native, settings)
    cam = native.camera if native.aniso is None else native.aniso.camera
    inst = cast_outputs(
        native.scene, cam, native.shapes, ("instance",), not native.variant.startswith("scalar"), native.parallel_rays
    )
    mask = np.isin(inst["instance"], native.catchers)
    # a catcher's edge against the background (the pixel centre sees nothing, the pixel partly the catcher
    # and nothing else: the same coverage with and without the other objects) is a catcher pixel too; before,
    # its plane colour drew a bright line along the catcher's far edge (Cycles shows nothing there)
    mask |= (inst["instance"] < 0) & (free[..., 3] > 0) & (rgba[..., 3] <= free[..., 3] + _EDGE_COVERAGE_TOLERANCE)
    lum = np.array([0.2126, 0.7152, 0.0722], np.float32)
    shadowed = rgba[..., :3] @ lum
    unshadowed = free[..., :3] @ lum
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(unshadowed > 1e-8, shadowed / unshadowed, 1.0)
    shadow = np.where(mask, np.clip(1.0 - ratio, 0.0, 1.0), 0.0)
    if native.objects_scene is not None:
        out = _film(native, native.objects_scene, settings)
        # an object's pixel that also covers a catcher: that part's alpha is the shadow of the catcher pixels
        # beside it (without this the objects' feet turned partly transparent where they meet the catcher)
        part = np.clip(rgba[..., 3] - out[..., 3], 0.0, 1.0)
        out[..., 3] += np.where(mask, 0.0, part * _neighbour_mean(shadow, mask))
    else:
        out = rgba.copy()
    out[mask, :3] = 0.0
    out[mask, 3] = shadow[mask] * free[mask, 3]
    return out


def _neighbour_mean(values: np.ndarray, where: np.ndarray) -> np.ndarray:
    """The mean of ``values`` over the pixels of the 3x3 neighbourhood where ``where`` holds (0: none)."""
    h, w = values.shape
    v = np.pad(np.where(where, values, 0.0), 1)
    n = np.pad(where.astype(np.float64), 1)
    total = sum(v[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3))
    count = sum(n[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3))
    return np.where(count > 0, total / np.maximum(count, 1.0), 0.0)  # type: ignore[no-any-return]


#: the second ray of every pixel passes this far (pixels) from its centre: Mitsuba's ray-triangle test is
#: not watertight, a ray exactly through an edge between two non-coplanar triangles can slip between them
#: (measured: the pixel-centre rays through the 45 degree meridian of the IR's UV sphere)
_SECOND_RAY_OFFSET = (2.6e-4, 1.4e-4)


def _rays(
    camera: Any, parallel: bool, offset: tuple[float, float] = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixel-centre rays (moved by ``offset`` pixels) clipped to [near, far] (planar): origins, directions,
    t_near, t_far, cos. ``parallel``: every ray is along the view direction (orthographic cameras), cos = 1."""
    vv, uu = np.mgrid[0 : camera.height, 0 : camera.width]
    pixels = np.stack([uu.ravel() + offset[0], vv.ravel() + offset[1]], axis=1).astype(np.float64)
    o, d = camera.pixel_rays(pixels)
    cos = d @ camera.viewdir
    if parallel:
        cos = np.ones(len(d))
    tn = camera.near / cos
    tf = camera.far / cos
    return o, d, tn, tf, cos


def cast_outputs(
    scene: Any,
    camera: Any,
    shapes: dict[str, ShapeInfo],
    outputs: tuple[str, ...],
    vectorised: bool,
    parallel: bool = False,
) -> dict[str, np.ndarray]:
    """Depth (planar z, +inf background), normal (world, shading; turned for back faces), albedo (the
    material colour input, linear) and instance (renderable index, -1 background) per pixel centre.
    ``parallel``: the camera's rays are parallel (orthographic cameras, ``MitsubaNative.parallel_rays``)."""
    shape_list = list(scene.shapes())
    ids = [s.id() for s in shape_list]
    want_albedo = "albedo" in outputs
    casts = []
    for offset in ((0.0, 0.0), _SECOND_RAY_OFFSET):
        o, d, tn, tf, cos = _rays(camera, parallel, offset)
        n = len(d)
        hit_t = np.full(n, np.inf)
        hit_shape = np.full(n, -1, dtype=np.int64)
        normal = np.zeros((n, 3), np.float32)
        albedo = np.zeros((n, 3), np.float32)
        if vectorised:
            _cast_vector(scene, shape_list, ids, shapes, o, d, tn, tf, hit_t, hit_shape, normal, albedo, want_albedo)
        else:
            _cast_scalar(scene, ids, shapes, o, d, tn, tf, hit_t, hit_shape, normal, albedo, want_albedo)
        casts.append((hit_t * cos, hit_shape, normal, albedo))
    # the centre ray's hit, unless the second ray found a surface clearly nearer (the centre ray slipped
    # through a crack between two triangles)
    (z, hit_shape, normal, albedo), (z2, shape2, normal2, albedo2) = casts
    slipped = np.isfinite(z2) & ~(z2 >= z * (1.0 - 1e-3))
    z[slipped], hit_shape[slipped], normal[slipped], albedo[slipped] = (
        z2[slipped],
        shape2[slipped],
        normal2[slipped],
        albedo2[slipped],
    )
    h, w = camera.height, camera.width
    out: dict[str, np.ndarray] = {}
    valid = hit_shape >= 0
    if "depth" in outputs:
        z = np.where(valid, z, np.inf)
        out["depth"] = z.reshape(h, w).astype(np.float32)
    if "normal" in outputs:
        out["normal"] = normal.reshape(h, w, 3)
    if "albedo" in outputs:
        out["albedo"] = albedo.reshape(h, w, 3)
    if "instance" in outputs:
        table = np.array([shapes[i].renderable if i in shapes else -1 for i in ids] + [-1], dtype=np.int32)
        out["instance"] = table[hit_shape].reshape(h, w)
    return out


def _cast_scalar(
    scene: Any,
    ids: list[str],
    shapes: dict[str, ShapeInfo],
    o: np.ndarray,
    d: np.ndarray,
    tn: np.ndarray,
    tf: np.ndarray,
    hit_t: np.ndarray,
    hit_shape: np.ndarray,
    normal: np.ndarray,
    albedo: np.ndarray,
    want_albedo: bool,
) -> None:
    import mitsuba as mi

    index = {sid: i for i, sid in enumerate(ids)}
    for k in range(len(d)):
        start = float(tn[k])
        dk = d[k]
        for _ in range(_MAX_PASS_THROUGH):
            ray = mi.Ray3f(o[k] + dk * start, dk)
            ray.maxt = float(tf[k]) - start
            si = scene.ray_intersect(ray)
            if not si.is_valid():
                break
            sid = si.shape.id()
            info = shapes.get(sid)
            if info is None:  # an area light's null-BSDF shape: look through it
                start += float(si.t) * (1.0 + 1e-6) + 1e-6
                continue
            hit_t[k] = start + float(si.t)
            hit_shape[k] = index[sid]
            nn = np.array(si.sh_frame.n, dtype=np.float64)
            if np.array(si.n, dtype=np.float64) @ dk > 0:  # a back face (by its geometric normal) is turned
                nn = -nn
            normal[k] = nn
            if want_albedo:
                if info.albedo is not None:
                    albedo[k] = info.albedo
                else:
                    albedo[k] = np.array(info.albedo_texture.eval(si), dtype=np.float32)[:3]
            break


def _cast_vector(
    scene: Any,
    shape_list: list[Any],
    ids: list[str],
    shapes: dict[str, ShapeInfo],
    o: np.ndarray,
    d: np.ndarray,
    tn: np.ndarray,
    tf: np.ndarray,
    hit_t: np.ndarray,
    hit_shape: np.ndarray,
    normal: np.ndarray,
    albedo: np.ndarray,
    want_albedo: bool,
) -> None:
    import drjit as dr
    import mitsuba as mi

    # pointer id of every shape -> its index in scene.shapes()
    ptr_ids = np.array(dr.reinterpret_array(mi.UInt32, scene.shapes_dr()), dtype=np.int64)
    lookup = {int(p): i for i, p in enumerate(ptr_ids)}
    is_light = np.array([sid not in shapes for sid in ids] + [False])
    todo = np.arange(len(d))
    start = tn.astype(np.float64).copy()
    for _ in range(_MAX_PASS_THROUGH):
        if len(todo) == 0:
            break
        si = _intersect(scene, o[todo], d[todo], start[todo], tf[todo])
        valid = np.array(si.is_valid(), dtype=bool)
        t = np.array(si.t, dtype=np.float64)
        ptr = np.array(dr.reinterpret_array(mi.UInt32, si.shape), dtype=np.int64)
        idx = np.array([lookup.get(int(p), len(ids)) for p in ptr], dtype=np.int64)
        idx[~valid] = len(ids)
        through = valid & is_light[idx]
        done = valid & ~through
        rows = todo[done]
        hit_t[rows] = start[rows] + t[done]
        hit_shape[rows] = idx[done]
        nn = _vec3(si.sh_frame.n)[done]
        # a back face (by its geometric normal, as Cycles and pyrender decide) is turned to the camera
        flip = np.einsum("ij,ij->i", _vec3(si.n)[done], d[rows]) > 0
        nn[flip] *= -1
        normal[rows] = nn
        start[todo[through]] += t[through] * (1.0 + 1e-6) + 1e-6
        todo = todo[through]
    if not want_albedo:
        return
    hit = hit_shape >= 0
    const = np.zeros((len(ids) + 1, 3), np.float32)
    varying: list[int] = []
    for i, sid in enumerate(ids):
        info = shapes.get(sid)
        if info is None:
            continue
        if info.albedo is not None:
            const[i] = info.albedo
        else:
            varying.append(i)
    albedo[hit] = const[hit_shape[hit]]
    for i in varying:
        rows = np.nonzero(hit_shape == i)[0]
        if len(rows) == 0:
            continue
        si = _intersect(scene, o[rows], d[rows], tn[rows], tf[rows])
        val = _vec3(shapes[ids[i]].albedo_texture.eval(si))
        albedo[rows] = val


def _vec3(v: Any) -> np.ndarray:
    """(N, 3) numpy array from a vectorised 3-vector or colour."""
    return np.stack([np.array(v[j], dtype=np.float64) for j in range(3)], axis=1)


def _intersect(scene: Any, o: np.ndarray, d: np.ndarray, start: np.ndarray, tf: np.ndarray) -> Any:
    import mitsuba as mi

    oo = o + d * start[:, None]
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(np.ascontiguousarray(oo[:, j], dtype=np.float32)) for j in range(3))),
        mi.Vector3f(*(mi.Float(np.ascontiguousarray(d[:, j], dtype=np.float32)) for j in range(3))),
    )
    ray.maxt = mi.Float(np.ascontiguousarray(tf - start, dtype=np.float32))
    return scene.ray_intersect(ray)
