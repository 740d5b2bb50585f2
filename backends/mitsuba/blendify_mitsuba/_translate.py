"""IR -> Mitsuba 3 scene dictionary (for ``mi.load_dict``), built in memory.

Conventions (measured, see shared/docs/CONVENTIONS.md): camera ``to_world = T_cv . diag(-1, -1, 1, 1)``,
``fov`` along x from fx, principal-point offsets ``((W/2 - cx') / W, (H/2 - cy') / H)`` with
``cx' = cx + 0.5``; orthographic principal points by translating the camera; lights in Blender's units
converted to Mitsuba's radiometry; every BSDF wrapped in ``twosided``; texture ``v -> 1 - v``.

Every renderable becomes one or more shapes whose dictionary keys start with ``r{index:05d}_`` so that
hits can be mapped back to the renderable (instance output). Shapes never share a BSDF object, which
keeps Mitsuba from merging them.

This module imports mitsuba: import it only after the variant is set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mitsuba as mi
import numpy as np

from blendify_core.errors import InvalidSceneError, UnsupportedFeatureError
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors
from blendify_core.ir.geometry import TriMesh
from blendify_core.ir.lights import AreaLight, PointLight, SpotLight, SunLight
from blendify_core.ir.renderables import PlaneMesh, PointCloud, SphereNURBS

__all__ = ["ShapeInfo", "Translation", "translate_scene", "camera_dict", "light_dicts"]

#: camera frame change OpenCV (+Z forward, +Y down, +X right) -> Mitsuba (+Z forward, +Y up, +X left)
MI_FROM_CV = np.diag([-1.0, -1.0, 1.0, 1.0])
#: Blender lights emit along local -Z; Mitsuba spots along local +Z: rotate 180 deg about X
_FLIP_Z = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass
class ShapeInfo:
    """What a Mitsuba shape stands for: the renderable's index, its albedo (constant or a texture)."""

    renderable: int
    albedo: np.ndarray | None  # (3,) constant linear albedo, or None when ``albedo_texture`` varies
    albedo_texture: Any = None  # a mitsuba Texture evaluated at hits (vertex colours, textures)


@dataclass
class Translation:
    """The result of :func:`translate_scene`."""

    scene_dict: dict[str, Any]
    shapes: dict[str, ShapeInfo]
    n_analytic_spheres: int = 0
    #: for transparent films with emissive surfaces and a background/environment light (then
    #: ``hide_emitters`` cannot be used): the shapes alone (coverage alpha) and the sky alone
    coverage_dict: dict[str, Any] | None = None
    background_dict: dict[str, Any] | None = None
    #: shadow catchers: the scene with the catcher planes as the only renderables, and their indices
    catcher_dict: dict[str, Any] | None = None
    catchers: list[int] = field(default_factory=list)


def _mat(m: np.ndarray) -> Any:
    return mi.ScalarTransform4f(np.asarray(m, dtype=np.float64).tolist())


def _rgb(c: Any) -> dict[str, Any]:
    return {"type": "rgb", "value": [float(x) for x in np.asarray(c, dtype=np.float64)[:3]]}


# ---------------------------------------------------------------------------------------------------
# camera
# ---------------------------------------------------------------------------------------------------


def camera_to_world_cv(camera: Any) -> np.ndarray:
    """``T_cv``: 4x4 camera-to-world of the OpenCV camera frame."""
    r, t = camera.opencv_extrinsics()
    m = np.eye(4)
    m[:3, :3] = r.T
    m[:3, 3] = -r.T @ t
    return m


def camera_dict(camera: Any, film: dict[str, Any], sampler: dict[str, Any]) -> dict[str, Any]:
    """The sensor dictionary of a pinhole (square pixels) or orthographic camera."""
    w, h = camera.width, camera.height
    t_cv = camera_to_world_cv(camera)
    cxp, cyp = camera.cx + 0.5, camera.cy + 0.5
    if camera.kind == "perspective":
        if not math.isclose(camera.fx, camera.fy, rel_tol=1e-9):
            raise UnsupportedFeatureError(
                "camera: Mitsuba's perspective sensor has square pixels only; fx != fy is rendered by "
                "the backend through a resampled square-pixel camera, not by camera_dict",
                feature="camera.anisotropic",
                backend="mitsuba",
            )
        return {
            "type": "perspective",
            "fov_axis": "x",
            "fov": math.degrees(2.0 * math.atan(w / (2.0 * camera.fx))),
            "principal_point_offset_x": (w / 2.0 - cxp) / w,
            "principal_point_offset_y": (h / 2.0 - cyp) / h,
            "near_clip": float(camera.near),
            "far_clip": float(camera.far),
            "to_world": _mat(t_cv @ MI_FROM_CV),
            "film": film,
            "sampler": sampler,
        }
    if camera.kind == "orthographic":
        s = camera.pixel_size
        shift = np.array([(w / 2.0 - cxp) * s, (h / 2.0 - cyp) * s, 0.0])
        m = t_cv.copy()
        m[:3, 3] = m[:3, 3] + m[:3, :3] @ shift
        half = camera.ortho_scale / 2.0
        return {
            "type": "orthographic",
            "near_clip": float(camera.near),
            "far_clip": float(camera.far),
            "to_world": _mat(m @ MI_FROM_CV @ np.diag([half, half, 1.0, 1.0])),
            "film": film,
            "sampler": sampler,
        }
    raise InvalidSceneError(f"camera: unsupported camera kind {camera.kind!r}")


# ---------------------------------------------------------------------------------------------------
# lights
# ---------------------------------------------------------------------------------------------------


def light_dicts(scene: Any) -> dict[str, dict[str, Any]]:
    """Emitters for the positioned lights, the background and the environment map."""
    out: dict[str, dict[str, Any]] = {}
    bounds = scene.bounds()
    for i, light in enumerate(scene.lights):
        if light.strength <= 0:
            continue
        key = f"light{i:04d}"
        col = light.linear_color
        m = light.matrix_world
        if isinstance(light, SpotLight):
            half = light.spot_size / 2.0
            b = light.spot_blend
            beam = math.acos(min(1.0, b + (1.0 - b) * math.cos(half)))
            out[key] = {
                "type": "spot",
                "intensity": _rgb(col * light.strength / (4.0 * math.pi)),
                "cutoff_angle": math.degrees(half),
                "beam_width": max(math.degrees(beam), 1e-4),
                "to_world": _mat(m @ _FLIP_Z),
            }
        elif isinstance(light, PointLight):
            r = float(light.shadow_soft_size)
            if r > 0 and bounds is not None:
                # a sphere far from everything it lights (radius < 1e-3 of the distance) is a point light
                # to within 0.1 %; Mitsuba's float32 sphere-emitter sampling breaks down there (a 0.25 m
                # sphere 1 km away came out 1.9x too bright, 3 km away black)
                nearest = np.clip(light.translation, bounds[0], bounds[1])
                if r < 1e-3 * float(np.linalg.norm(light.translation - nearest)):
                    r = 0.0
            if r > 0:
                # Blender's sphere light (soft falloff off): a sphere emitter of radiance P / (4 pi^2 r^2)
                out[key] = {
                    "type": "sphere",
                    "center": [float(x) for x in light.translation],
                    "radius": r,
                    "bsdf": {"type": "null"},
                    "emitter": {"type": "area", "radiance": _rgb(col * light.strength / (4.0 * math.pi**2 * r * r))},
                }
            else:
                out[key] = {
                    "type": "point",
                    "intensity": _rgb(col * light.strength / (4.0 * math.pi)),
                    "position": [float(x) for x in light.translation],
                }
        elif isinstance(light, SunLight):
            out[key] = {
                "type": "directional",
                "irradiance": _rgb(col * light.strength),
                "direction": [float(x) for x in light.direction],
            }
        elif isinstance(light, AreaLight):
            a, b = light.size
            disk = light.shape in ("circle", "ellipse")
            out[key] = {
                "type": "disk" if disk else "rectangle",
                "to_world": _mat(m @ np.diag([a / 2.0, b / 2.0, 1.0, 1.0])),
                "flip_normals": True,
                "bsdf": {"type": "null"},
                "emitter": {"type": "area", "radiance": _rgb(light.radiance)},
            }
        else:  # pragma: no cover - the IR has no other light kinds
            raise UnsupportedFeatureError(f"light {light.tag!r}: unknown light kind {light.kind!r}")
    bg = scene.lights.background
    env = scene.lights.environment
    if env is not None and env.strength > 0:
        # Mitsuba takes one environment emitter: a background light is added to the map (as Cycles adds
        # the two Background shaders)
        out["environment"] = environment_dict(env, scene_background(scene))
    elif bg is not None and bg.strength > 0:
        out["background"] = {"type": "constant", "radiance": _rgb(bg.radiance)}
    return out


def scene_background(scene: Any) -> np.ndarray | None:
    """The background light's radiance (3,), or None."""
    bg = scene.lights.background
    return None if bg is None or bg.strength <= 0 else np.asarray(bg.radiance, dtype=np.float64)


def environment_dict(env: Any, add: np.ndarray | None = None) -> dict[str, Any]:
    """An ``envmap`` reproducing :func:`blendify_core.ir.lights.equirect_uv`.

    Mitsuba's envmap looks up the local direction d at u = atan2(d_x, -d_z) / (2 pi) (mod 1),
    v = acos(d_y) / pi (v = 0 at the top row). Blender's mapping of a world direction w is
    u = 0.5 - atan2(w_y, w_x) / (2 pi), v_top = acos(w_z) / pi. With local = (w_y, w_z, w_x) both agree
    (atan2(w_y, -w_x) = pi - atan2(w_y, w_x)): to_world maps local x -> world y, y -> z, z -> x (a
    proper rotation), composed with the map's own rotation."""
    img = env.linear_rgb_image().astype(np.float32) * np.float32(env.strength)
    if add is not None:
        img = img + np.asarray(add, dtype=np.float32)[None, None, :3]
    local_to_world = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    m = np.eye(4)
    m[:3, :3] = env.rotation_matrix @ local_to_world
    return {
        "type": "envmap",
        "bitmap": mi.Bitmap(np.ascontiguousarray(img)),
        "to_world": _mat(m),
    }


# ---------------------------------------------------------------------------------------------------
# materials
# ---------------------------------------------------------------------------------------------------


def _effective_eta(ior: float, level: float) -> float:
    """Blender's "Specular IOR Level" scales F0 by 2 * level; return the IOR with that F0."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    f0 = min(max(f0, 1e-6), 0.99)
    s = math.sqrt(f0)
    return (1.0 + s) / (1.0 - s)


def bsdf_dict(material: Any, color: Any) -> tuple[dict[str, Any], str]:
    """The (two-sided) BSDF for one material and its colour texture/value; returns (dict, kind)."""
    v = material.parameters()
    if material.kind == "glossy":
        r = float(v["roughness"])
        inner: dict[str, Any] = {"type": "conductor", "material": "none", "specular_reflectance": color}
        if r > 0:
            inner = {
                "type": "roughconductor",
                "material": "none",
                "distribution": "beckmann" if v["distribution"] == "BECKMANN" else "ggx",
                "alpha": max(r * r, 1e-4),
                "specular_reflectance": color,
            }
        kind = "glossy"
    elif material.is_diffuse_only:
        inner = {"type": "diffuse", "reflectance": color}
        kind = "diffuse"
    else:
        rough: Any = float(v["roughness"])
        metal: Any = float(v["metallic"])
        if v.get("roughness_map") is not None:
            rough = _data_texture(v["roughness_map"].values())
        if v.get("metallic_map") is not None:
            metal = _data_texture(v["metallic_map"].values())
        eta = _effective_eta(float(v["ior"]), float(v["specular_ior"]))
        inner = {
            "type": "principled",
            "base_color": color,
            "metallic": metal,
            "roughness": rough,
            "eta": max(eta, 1.0001),
            "anisotropic": float(v["anisotropic"]),
            "spec_trans": float(v["transmission_weight"]),
            "clearcoat": float(v["coat_weight"]),
            "clearcoat_gloss": 1.0 - float(v["coat_roughness"]),
            "sheen": float(v["sheen_weight"]),
        }
        kind = "principled"
    nmap = v.get("normal_map")
    if nmap is not None:
        inner = {"type": "normalmap", "normalmap": _normal_texture(nmap), "bsdf": inner}
    if kind == "principled" and float(v["transmission_weight"]) > 0:
        return inner, kind  # transmission needs both sides to be distinct
    return {"type": "twosided", "bsdf": inner}, kind


def _data_texture(values: np.ndarray) -> dict[str, Any]:
    """A raw (never colour-managed) single-channel bitmap; UVs are v-flipped like colour textures."""
    data = np.ascontiguousarray(np.asarray(values, dtype=np.float32)[..., None])
    return {"type": "bitmap", "data": mi.TensorXf(data), "raw": True, "filter_type": "bilinear"}


def _normal_texture(nmap: Any) -> dict[str, Any]:
    """The tangent-space normal map for Mitsuba's ``normalmap`` BSDF, with Blender's ``strength`` baked in
    (n' = normalize(N + s (n - N)) with N = (0, 0, 1) in tangent space). Mitsuba's shading frame is
    (dp/du, n x dp/du), Blender's tangent frame for UVs of the usual orientation; the v -> 1 - v flip of
    the UVs does not change dp/du."""
    n = nmap.normals().astype(np.float64)
    s = float(nmap.strength)
    n = np.stack([s * n[..., 0], s * n[..., 1], 1.0 + s * (n[..., 2] - 1.0)], axis=-1)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    data = np.ascontiguousarray(((n + 1.0) * 0.5).astype(np.float32))
    return {"type": "bitmap", "data": mi.TensorXf(data), "raw": True, "filter_type": "bilinear"}


# ---------------------------------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------------------------------


def _world(vertices: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    return np.asarray(vertices, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def build_mesh(
    name: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray | None = None,
    uv: np.ndarray | None = None,
    attributes: dict[str, np.ndarray] | None = None,
    bsdf: Any = None,
    emitter: Any = None,
) -> Any:
    """A ``mi.Mesh`` from numpy buffers (world-space vertices; ``uv`` per vertex, already v-flipped)."""
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    if emitter is not None:
        props["emitter"] = emitter
    mesh = mi.Mesh(name, len(vertices), len(faces), props, normals is not None, uv is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(vertices, dtype=np.float32).ravel()
    params["faces"] = np.ascontiguousarray(faces, dtype=np.uint32).ravel()
    if normals is not None:
        params["vertex_normals"] = np.ascontiguousarray(normals, dtype=np.float32).ravel()
    if uv is not None:
        params["vertex_texcoords"] = np.ascontiguousarray(uv, dtype=np.float32).ravel()
    params.update()
    for attr_name, values in (attributes or {}).items():
        arr = np.ascontiguousarray(values, dtype=np.float32)
        mesh.add_attribute(attr_name, 1 if arr.ndim == 1 else arr.shape[1], arr.ravel())
    return mesh


#: 8-bit sRGB textures with linear interpolation: Cycles interpolates the *encoded* bytes and decodes
#: afterwards (a texel boundary between bytes 30 and 230 gives decode(130) = 0.22, Mitsuba's linear-space
#: interpolation 0.40). To match, such textures are upsampled in encoded space (exact bilinear at the
#: new texel centres), decoded, and interpolated by Mitsuba between those: the residual error shrinks as
#: 1/k^2. Only textures up to this many texels are upsampled (larger ones are usually minified).
SRGB_UPSAMPLE_MAX_TEXELS = 1024 * 1024


def _texture_dict(colors: Any, channel: str = "rgb") -> dict[str, Any]:
    """A ``bitmap`` for texture colours (``channel`` "rgb" or "alpha")."""
    filt = "nearest" if colors.interpolation == "closest" else "bilinear"
    raw_img = colors.image()
    srgb_bytes = raw_img.dtype == np.uint8 and colors.color_space == "srgb"
    if channel == "rgb" and isinstance(colors, FileTextureColors) and (filt == "nearest" or not srgb_bytes):
        suffix = Path(colors.texture_path).suffix.lower()
        if suffix in (".png", ".jpg", ".jpeg") and raw_img.dtype == np.uint8:
            # Mitsuba decodes 8-bit sRGB itself unless raw=True (same meaning as the IR's colour space)
            return {
                "type": "bitmap",
                "filename": colors.texture_path,
                "raw": colors.color_space == "linear",
                "filter_type": filt,
            }
    if channel == "rgb" and filt == "bilinear" and srgb_bytes:
        h, w = raw_img.shape[:2]
        k = int(max(1, min(8, math.floor(math.sqrt(SRGB_UPSAMPLE_MAX_TEXELS / (h * w))))))
        if k > 1:
            from blendify_core.ir.colorspace import srgb_to_linear

            enc = raw_img.astype(np.float32)[..., :3] / 255.0
            if enc.shape[2] == 1:
                enc = np.repeat(enc, 3, axis=2)
            up = _upsample_bilinear_repeat(enc, k)
            data = np.asarray(srgb_to_linear(up), dtype=np.float32)
            return {"type": "bitmap", "data": mi.TensorXf(np.ascontiguousarray(data)), "raw": True, "filter_type": filt}
    img = colors.linear_rgba_image()
    data = img[..., :3] if channel == "rgb" else img[..., 3:4]
    return {
        "type": "bitmap",
        "data": mi.TensorXf(np.ascontiguousarray(data, dtype=np.float32)),
        "raw": True,
        "filter_type": filt,
    }


def _linear_weights(n: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1-D bilinear (texel centres at (i + 0.5) / n, repeat wrap) sampled at the k n new texel centres:
    indices i0, i1 and the weight of i1."""
    x = (np.arange(n * k) + 0.5) / k - 0.5
    x0 = np.floor(x)
    f = (x - x0).astype(np.float32)
    i0 = x0.astype(np.int64) % n
    return i0, (i0 + 1) % n, f


def _upsample_bilinear_repeat(img: np.ndarray, k: int) -> np.ndarray:
    """(H, W, C) -> (k H, k W, C): the bilinear interpolant of ``img`` at the centres of a k-times finer grid."""
    h, w = img.shape[:2]
    r0, r1, fr = _linear_weights(h, k)
    rows = img[r0] * (1.0 - fr)[:, None, None] + img[r1] * fr[:, None, None]
    c0, c1, fc = _linear_weights(w, k)
    return rows[:, c0] * (1.0 - fc)[None, :, None] + rows[:, c1] * fc[None, :, None]


@dataclass
class _Part:
    """One Mitsuba mesh (a material slot of a renderable), in world space."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uv: np.ndarray | None
    source: np.ndarray  # index of each part vertex in the renderable's vertex array


def _split(tm: TriMesh, matrix: np.ndarray, faces_material: np.ndarray | None, n_mat: int) -> list[Any]:
    """Split a TriMesh by material; de-index per corner when UVs are per corner."""
    rot = matrix[:3, :3]
    v_world = _world(tm.vertices, matrix)
    n_world = None if tm.normals is None or not tm.smooth else np.asarray(tm.normals, dtype=np.float64) @ rot.T
    parts: list[Any] = []
    for k in range(n_mat):
        sel = np.arange(len(tm.faces)) if faces_material is None else np.nonzero(faces_material == k)[0]
        if len(sel) == 0:
            parts.append(None)
            continue
        f = np.asarray(tm.faces)[sel]
        if tm.uv is not None:
            # per-corner UVs: one vertex per corner
            idx = f.ravel()
            uv = np.asarray(tm.uv, dtype=np.float64)[sel].reshape(-1, 2).copy()
            uv[:, 1] = 1.0 - uv[:, 1]
            parts.append(
                _Part(
                    v_world[idx],
                    np.arange(len(idx)).reshape(-1, 3),
                    None if n_world is None else n_world[idx],
                    uv,
                    idx,
                )
            )
        else:
            used, inv = np.unique(f.ravel(), return_inverse=True)
            parts.append(
                _Part(
                    v_world[used],
                    inv.reshape(-1, 3),
                    None if n_world is None else n_world[used],
                    None,
                    used,
                )
            )
    return parts


# ---------------------------------------------------------------------------------------------------
# the scene
# ---------------------------------------------------------------------------------------------------


def _emission(material: Any) -> np.ndarray | None:
    if not material.is_emissive:
        return None
    return material.linear("emission_color")[:3] * float(material.get("emission_strength"))


def _color_source(colors: Any, key: str) -> tuple[Any, np.ndarray | None, Any]:
    """(Mitsuba reflectance value/texture, constant albedo or None, evaluable texture or None)."""
    if isinstance(colors, UniformColors):
        c = colors.linear_rgba[:3]
        return _rgb(c), c, None
    if isinstance(colors, VertexColors):
        tex = mi.load_dict({"type": "mesh_attribute", "name": "vertex_color"})
        return tex, None, tex
    if isinstance(colors, (TextureColors, FileTextureColors)):
        tex = mi.load_dict(_texture_dict(colors))
        return tex, None, tex
    raise InvalidSceneError(f"colors: unsupported colour source {type(colors).__name__} on {key}")


def _opacity(material: Any, colors: Any) -> tuple[Any, bool]:
    """Opacity value or texture for a ``mask`` wrapper, and whether one is needed."""
    alpha = float(material.parameters().get("alpha", 1.0))
    if isinstance(colors, UniformColors):
        a = alpha * float(colors.linear_rgba[3])
        return a, a < 1.0
    if isinstance(colors, VertexColors) and colors.has_alpha:
        return {"type": "mesh_attribute", "name": "vertex_alpha", "scale": alpha}, True
    if isinstance(colors, (TextureColors, FileTextureColors)) and colors.has_alpha:
        d = _texture_dict(colors, "alpha")
        if alpha < 1.0:
            data = np.array(d["data"]) * np.float32(alpha)
            d["data"] = mi.TensorXf(data.astype(np.float32))
        return d, True
    return alpha, alpha < 1.0


def translate_scene(
    scene: Any,
    film: dict[str, Any],
    sampler: dict[str, Any],
    integrator: dict[str, Any],
    max_analytic_spheres: int,
    camera: Any = None,
    composite: bool = False,
) -> Translation:
    """Build the ``mi.load_dict`` dictionary of ``scene`` (camera replaced by ``camera`` if given).

    ``composite``: also build the coverage and sky scenes used to recover a coverage alpha when
    ``hide_emitters`` cannot be used (emissive surfaces would vanish from camera rays with it)."""
    cam = scene.camera if camera is None else camera
    d: dict[str, Any] = {
        "type": "scene",
        "integrator": integrator,
        "sensor": camera_dict(cam, film, sampler),
    }
    shapes: dict[str, ShapeInfo] = {}
    n_spheres = 0
    catchers: list[int] = []
    for ri, r in enumerate(scene.renderables):
        prefix = f"r{ri:05d}"
        if isinstance(r, PlaneMesh) and r.shadow_catcher:
            catchers.append(ri)
        if not r.emit_shadows:
            raise UnsupportedFeatureError(
                f"renderable {r.tag!r}: emit_shadows=False has no Mitsuba equivalent",
                feature="object.no_shadow",
                backend="mitsuba",
            )
        matrix = r.matrix_world
        if isinstance(r, PointCloud):
            n_spheres += _add_pointcloud(d, shapes, r, ri, prefix, matrix, max_analytic_spheres)
            continue
        if isinstance(r, SphereNURBS):
            mat, colors = r.materials[0], r.colors_list[0]
            refl, const, tex = _color_source(colors, prefix)
            bsdf, _ = bsdf_dict(mat, refl)
            bsdf = _wrap_mask(bsdf, mat, colors)
            key = f"{prefix}_sphere"
            shape = {
                "type": "sphere",
                "center": [float(x) for x in r.translation],
                "radius": float(r.radius),
                "bsdf": bsdf,
            }
            em = _emission(mat)
            if em is not None:
                shape["emitter"] = {"type": "area", "radiance": _rgb(em)}
            d[key] = shape
            shapes[key] = ShapeInfo(ri, const, tex)
            continue
        # meshes, mesh primitives, ellipsoids and curves: the IR's tessellation
        tm = r.to_mesh()
        if tm.is_empty:
            continue
        fm = getattr(r, "faces_material", None)  # meshes and mesh primitives: per-triangle slots
        parts = _split(tm, matrix, fm, len(r.materials))
        for k, (mat, colors, part) in enumerate(zip(r.materials, r.colors_list, parts, strict=True)):
            if part is None:
                continue
            key = f"{prefix}_m{k:03d}"
            refl, const, tex = _color_source(colors, key)
            if isinstance(colors, (TextureColors, FileTextureColors)) and part.uv is None:
                raise InvalidSceneError(f"renderable {r.tag!r}: texture colours need a UV map")
            bsdf_d, _ = bsdf_dict(mat, refl)
            bsdf = mi.load_dict(_wrap_mask(bsdf_d, mat, colors))
            em = _emission(mat)
            emitter = mi.load_dict({"type": "area", "radiance": _rgb(em)}) if em is not None else None
            attrs: dict[str, np.ndarray] = {}
            if isinstance(colors, VertexColors):
                rgba = colors.linear_rgba[part.source]
                attrs["vertex_color"] = rgba[:, :3]
                if colors.has_alpha:
                    attrs["vertex_alpha"] = rgba[:, 3]
            mesh = build_mesh(key, part.vertices, part.faces, part.normals, part.uv, attrs, bsdf, emitter)
            d[key] = mesh
            shapes[key] = ShapeInfo(ri, const, tex)
            if mat.has_wireframe:
                _add_wireframe(d, shapes, f"{prefix}_w{k:03d}", ri, mat, part)
    d.update(light_dicts(scene))
    coverage_dict = background_dict = None
    sky = {k: v for k, v in d.items() if k in ("environment", "background")}
    if composite and sky:
        # max_depth 2: Mitsuba's path integrator records a hit in the alpha only once it decides to continue
        # the path (with max_depth 1 only emitters count); the scene has no lights, so this stays cheap
        two = {"type": "path", "max_depth": 2, "hide_emitters": False}
        one = {"type": "path", "max_depth": 1, "hide_emitters": False}
        coverage_dict = {
            "type": "scene",
            "integrator": two,
            "sensor": camera_dict(cam, film, sampler),
            **{k: v for k, v in d.items() if k.startswith("r")},
        }
        sky_dict = {
            k: (environment_dict(scene.lights.environment, scene_background(scene)) if k == "environment" else v)
            for k, v in sky.items()
        }
        background_dict = {"type": "scene", "integrator": one, "sensor": camera_dict(cam, film, sampler), **sky_dict}
    catcher_dict = None
    if catchers:
        # the catchers alone under the same lights: the unshadowed radiance of the shadow-catcher emulation
        own = tuple(f"r{ri:05d}_" for ri in catchers)
        catcher_dict = {k: v for k, v in d.items() if not k.startswith("r") or k.startswith(own)}
        if "environment" in catcher_dict:
            catcher_dict["environment"] = environment_dict(scene.lights.environment, scene_background(scene))
        catcher_dict["sensor"] = camera_dict(cam, film, sampler)
    return Translation(
        d,
        shapes,
        n_spheres,
        coverage_dict=coverage_dict,
        background_dict=background_dict,
        catcher_dict=catcher_dict,
        catchers=catchers,
    )


def wire_tubes(vertices: np.ndarray, faces: np.ndarray, thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """Every distinct triangle edge as an open square tube of side ``thickness`` centred on the edge and
    extended by thickness / 2 at both ends (so corners close): (V, 3) vertices and (F, 3) triangles."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [0, 2]]]), axis=1)
    edges = np.unique(edges, axis=0)
    p0, p1 = vertices[edges[:, 0]], vertices[edges[:, 1]]
    axis = p1 - p0
    length = np.linalg.norm(axis, axis=1)
    ok = length > 0
    p0, p1, axis, length = p0[ok], p1[ok], axis[ok], length[ok]
    axis /= length[:, None]
    half = thickness / 2.0
    p0, p1 = p0 - axis * half, p1 + axis * half
    ref = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    side = np.cross(axis, ref)
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    up = np.cross(axis, side)
    offsets = np.stack([side + up, up - side, -side - up, side - up], axis=1) * half  # (E, 4, 3)
    verts = np.concatenate([p0[:, None] + offsets, p1[:, None] + offsets], axis=1)  # (E, 8, 3)
    a = np.arange(4)
    b = (a + 1) % 4
    quads = np.concatenate([np.stack([a, b, b + 4], 1), np.stack([a, b + 4, a + 4], 1)])  # (8, 3)
    tris = quads[None] + (8 * np.arange(len(p0)))[:, None, None]
    return verts.reshape(-1, 3), tris.reshape(-1, 3)


def _add_wireframe(
    d: dict[str, Any], shapes: dict[str, ShapeInfo], key: str, ri: int, material: Any, part: _Part
) -> None:
    """The wireframe overlay as geometry: square tubes along the edges, with the surface's BSDF in the
    wireframe colour (as the Cycles backend mixes a second Principled in that colour along the edges)."""
    thickness = float(material.get("wireframe_thickness"))
    if thickness <= 0 or len(part.faces) == 0:
        return
    verts, tris = wire_tubes(part.vertices, np.asarray(part.faces), thickness)
    if len(tris) == 0:
        return
    wire = material.linear("wireframe_color")
    bsdf_d, _ = bsdf_dict(material, _rgb(wire[:3]))
    if wire[3] < 1.0:
        bsdf_d = {"type": "mask", "opacity": float(wire[3]), "bsdf": bsdf_d}
    d[key] = build_mesh(key, verts, tris, bsdf=mi.load_dict(bsdf_d))
    shapes[key] = ShapeInfo(ri, np.asarray(wire[:3], dtype=np.float64))


def _wrap_mask(bsdf: dict[str, Any], material: Any, colors: Any) -> dict[str, Any]:
    opacity, needed = _opacity(material, colors)
    if not needed:
        return bsdf
    return {"type": "mask", "opacity": opacity, "bsdf": bsdf}


def _add_pointcloud(
    d: dict[str, Any],
    shapes: dict[str, ShapeInfo],
    r: PointCloud,
    ri: int,
    prefix: str,
    matrix: np.ndarray,
    max_analytic: int,
) -> int:
    """Analytic spheres (one shape and BSDF per point) up to ``max_analytic`` points, else one merged
    icosphere mesh with per-vertex colours. Returns the number of analytic spheres added."""
    mat, colors = r.materials[0], r.colors_list[0]
    centres = _world(r.vertices, matrix)
    radii = r.radii()
    n = len(centres)
    if n == 0:
        return 0
    per_point = colors.linear_rgba[:, :3] if isinstance(colors, VertexColors) else None
    uniform = None if per_point is not None else colors.linear_rgba[:3]
    strength = r.particle_emission_strength
    if n <= max_analytic:
        for i in range(n):
            c = per_point[i] if per_point is not None else uniform
            bsdf, _ = bsdf_dict(mat, _rgb(c))
            own = colors
            if per_point is not None:  # this point's alpha (linear RGBA: no decoding)
                own = UniformColors((1.0, 1.0, 1.0, float(colors.linear_rgba[i, 3])), color_space="linear")
            bsdf = _wrap_mask(bsdf, mat, own)
            key = f"{prefix}_p{i:07d}"
            shape = {"type": "sphere", "center": centres[i].tolist(), "radius": float(radii[i]), "bsdf": bsdf}
            em = _emission(mat)
            if strength > 0:
                em = (em if em is not None else 0.0) + np.asarray(c) * strength
            if em is not None:
                shape["emitter"] = {"type": "area", "radiance": _rgb(em)}
            d[key] = shape
            shapes[key] = ShapeInfo(ri, np.asarray(c, dtype=np.float64))
        return n
    tm = r.to_mesh()
    # to_mesh works in object space around the raw vertices: move to world space
    verts = _world(tm.vertices, matrix)
    normals = np.asarray(tm.normals, dtype=np.float64) @ matrix[:3, :3].T
    nv = len(tm.vertices) // n
    key = f"{prefix}_mesh"
    attrs: dict[str, np.ndarray] = {}
    if per_point is not None:
        refl: Any = mi.load_dict({"type": "mesh_attribute", "name": "vertex_color"})
        attrs["vertex_color"] = np.repeat(per_point, nv, axis=0)
        if colors.has_alpha:
            attrs["vertex_alpha"] = np.repeat(colors.linear_rgba[:, 3], nv)
        const, tex = None, refl
    else:
        refl, const, tex = _rgb(uniform), np.asarray(uniform, dtype=np.float64), None
    bsdf = mi.load_dict(_wrap_mask(bsdf_dict(mat, refl)[0], mat, colors))
    emitter = None
    em = _emission(mat)
    if strength > 0:
        if per_point is not None:
            rad: Any = {"type": "mesh_attribute", "name": "vertex_color", "scale": strength}
            if em is not None:
                raise UnsupportedFeatureError(
                    "pointcloud: material emission combined with per-point particle emission",
                    feature="pointcloud.emission",
                    backend="mitsuba",
                )
        else:
            rad = _rgb((em if em is not None else 0.0) + uniform * strength)
        emitter = mi.load_dict({"type": "area", "radiance": rad})
    elif em is not None:
        emitter = mi.load_dict({"type": "area", "radiance": _rgb(em)})
    mesh = build_mesh(key, verts, tm.faces, normals, None, attrs, bsdf, emitter)
    d[key] = mesh
    shapes[key] = ShapeInfo(ri, const, tex)
    return 0
