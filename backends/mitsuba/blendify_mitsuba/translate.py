"""IR -> Mitsuba 3 scene dictionary (for ``mi.load_dict``), built in memory: one handler per IR type.

:class:`MitsubaTranslator` has one ``@handles`` method per IR type (a sphere is translated by
:meth:`MitsubaTranslator.sphere`, a spot light by :meth:`MitsubaTranslator.spot_light`, ...) and declares
beside each handler the capabilities of the features it implements; :meth:`MitsubaTranslator.translate`
walks the scene through :meth:`~blendify_core.pipeline.translator.Translator.dispatch`.

Conventions (measured, see shared/docs/CONVENTIONS.md): camera ``to_world = T_cv . diag(-1, -1, 1, 1)``,
``fov`` along x from fx, principal-point offsets ``((W/2 - cx') / W, (H/2 - cy') / H)`` with
``cx' = cx + 0.5``; orthographic principal points by translating the camera; lights in Blender's units
converted to Mitsuba's radiometry (:mod:`blendify_core.ir.physics`); every BSDF wrapped in ``twosided``;
texture ``v -> 1 - v``. Non-square pixels (fx != fy) are rendered through a square-pixel camera
(:mod:`blendify_mitsuba.aniso`).

Every renderable becomes one or more shapes whose dictionary keys start with ``r{index:05d}_`` so that
hits can be mapped back to the renderable (instance output). Shapes never share a BSDF object, which
keeps Mitsuba from merging them.

Mitsuba is imported inside the functions that build engine objects, so importing this module loads no
engine; the session (:mod:`blendify_mitsuba.session`) sets the variant before any translation.
"""

from __future__ import annotations

import contextvars
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError, UnsupportedFeatureError
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors
from blendify_core.ir.colorspace import srgb_to_linear
from blendify_core.ir.geometry import TriMesh, leaning_area_fraction
from blendify_core.ir.lights import AreaLight, BackgroundLight, EnvironmentMap, PointLight, SpotLight, SunLight
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    MetalMaterial,
    MetalWireframeMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
from blendify_core.ir.physics import (
    blend_normal_map,
    material_lobes,
    point_intensity,
    sphere_light_radiance,
    spot_cone,
    spot_falloff,
)
from blendify_core.ir.renderables import (
    CircleMesh,
    CubeMesh,
    CurveBezier,
    CylinderMesh,
    EllipsoidNURBS,
    Mesh,
    PlaneMesh,
    PointCloud,
    SphereNURBS,
)
from blendify_core.pipeline.capabilities import Capability
from blendify_core.pipeline.effects import Effects, analyse_effects
from blendify_core.pipeline.settings import RenderSettings, resolve_settings
from blendify_core.pipeline.translator import EXACT, TranslationContext, Translator, approximate, handles, unsupported

from . import layered
from .aniso import SquarePixelPlan, plan_square_pixels
from .integrator import register as register_integrator
from .layered import register as register_layered
from .points import curve_points, curves_fit, point_bitmap
from .principled import glossy_scale, layered_bsdf, principled_bsdf, principled_lobes, raw_rgb, with_bitmaps
from .sided import register as register_sided

__all__ = [
    "MitsubaContext",
    "MitsubaTranslator",
    "ShapeInfo",
    "Translation",
    "build_mesh",
    "wire_bands",
    "DEFAULT_SAMPLER",
    "BACKGROUND_SAMPLING_WEIGHT",
]

#: Mitsuba's sampler plugin by default: ``multijitter`` (correlated multi-jittered) has 1/2 (sun) to 1/4
#: (area light) of ``independent``'s per-pixel noise at equal spp, within Cycles' (its Sobol-Burley
#: pattern), for 1.2x (llvm) to 1.9x (scalar) the time per sample (benchmarks/results/mitsuba_noise.md)
DEFAULT_SAMPLER = "multijitter"
#: the uniform background's light-sampling weight beside the other emitters' 1 (see background_light)
BACKGROUND_SAMPLING_WEIGHT = 1e-3

#: camera frame change OpenCV (+Z forward, +Y down, +X right) -> Mitsuba (+Z forward, +Y up, +X left)
MI_FROM_CV = np.diag([-1.0, -1.0, 1.0, 1.0])
#: Blender lights emit along local -Z; Mitsuba spots along local +Z: rotate 180 deg about X
_FLIP_Z = np.diag([1.0, -1.0, -1.0, 1.0])

#: 8-bit sRGB textures with linear interpolation: Cycles interpolates the *encoded* bytes and decodes
#: afterwards (a texel boundary between bytes 30 and 230 gives decode(130) = 0.22, Mitsuba's linear-space
#: interpolation 0.40). To match, such textures are upsampled in encoded space (exact bilinear at the
#: new texel centres), decoded, and interpolated by Mitsuba between those: the residual error shrinks as
#: 1/k^2. Only textures up to this many texels are upsampled (larger ones are usually minified).
SRGB_UPSAMPLE_MAX_TEXELS = 1024 * 1024


def _exact(note: str) -> Capability:
    """An exact feature with a note on how it is done."""
    return Capability("exact", note)


#: the engine the translator builds with: None = the mitsuba module; the XML exporter
#: (:mod:`blendify_mitsuba.export`) sets a stand-in that keeps the plain dictionaries and arrays instead
ENGINE: contextvars.ContextVar[Any] = contextvars.ContextVar("blendify_mitsuba_engine", default=None)


def _layered_variant() -> bool:
    """Whether Principled materials become :mod:`blendify_mitsuba.layered` BSDFs: in the JIT variants (Dr.Jit
    traces the Python BSDF into the kernel); not in ``scalar_rgb`` (one Python call per sample) and not when
    exporting a scene file (plain Mitsuba has no such plugin)."""
    if ENGINE.get() is not None or not layered.ENABLED:
        return False
    import mitsuba

    return layered.USE_IN_SCALAR or not mitsuba.variant().startswith("scalar")


#: at most this many distinct layered BSDFs per scene: Dr.Jit traces each distinct Python BSDF at the first
#: render (about 65 ms each, measured: 200 per-point colours took 17.8 s against 4.7 s with the lobe sum)
LAYERED_MAX_DISTINCT = 32


def _layered_specs(d: Any) -> set[str]:
    """The ``spec`` strings of the layered plugins in the BSDF dictionary ``d``."""
    if not isinstance(d, dict):
        return set()
    out = {d["spec"]} if d.get("type") in (layered.PLUGIN, layered.GLASS_PLUGIN) else set()
    for v in d.values():
        out |= _layered_specs(v)
    return out


def _room_for_layered(ctx: MitsubaContext | None, d: Any) -> bool:
    """Whether the scene may hold the layered BSDFs of ``d`` (recorded in ``ctx`` if so)."""
    if ctx is None:
        return True
    specs = _layered_specs(d)
    if len(ctx.layered_specs | specs) > LAYERED_MAX_DISTINCT:
        return False
    ctx.layered_specs |= specs
    return True


def _mi() -> Any:
    """The mitsuba module (its variant is set by the session before any translation), or the stand-in
    engine set in :data:`ENGINE`."""
    engine = ENGINE.get()
    if engine is not None:
        return engine
    import mitsuba

    return mitsuba


@dataclass
class ShapeInfo:
    """What a Mitsuba shape stands for: the renderable's index, its albedo (constant or a texture)."""

    renderable: int
    albedo: np.ndarray | None  # (3,) constant linear albedo, or None when ``albedo_texture`` varies
    albedo_texture: Any = None  # a mitsuba Texture evaluated at hits (vertex colours, textures)


@dataclass
class Translation:
    """The result of :meth:`MitsubaTranslator.translate`: the dictionaries to load and what they mean."""

    scene_dict: dict[str, Any]
    shapes: dict[str, ShapeInfo]
    n_analytic_spheres: int = 0
    #: for transparent films with emissive surfaces and a background/environment light (then
    #: ``hide_emitters`` cannot be used): the shapes alone (coverage alpha) and the sky alone
    coverage_dict: dict[str, Any] | None = None
    background_dict: dict[str, Any] | None = None
    #: the sky's radiance (3,) when it is a constant background: what background_dict renders, without a render
    sky_radiance: list[float] | None = None
    #: shadow catchers: the scene with the catcher planes as the only renderables, and their indices
    catcher_dict: dict[str, Any] | None = None
    catchers: list[int] = field(default_factory=list)
    #: ... and the scene without the catchers: what the other objects look like (a catcher neither lights nor
    #: shades them in Cycles)
    objects_dict: dict[str, Any] | None = None
    #: the ids of the light shapes (point lights with a radius, area lights) when the integrator cannot hide
    #: them from the camera: the render removes their directly seen emission (render.seen_lights)
    light_shapes: list[str] = field(default_factory=list)
    integrator: dict[str, Any] = field(default_factory=dict)
    effects: Effects | None = None
    #: samples per rendered pixel (differs from settings.samples for fx != fy) and the square-pixel plan
    spp: int = 1
    aniso: SquarePixelPlan | None = None
    ignored: list[str] = field(default_factory=list)
    #: approximations this scene needed beyond the capability table (result.meta["approximations"])
    approximations: list[str] = field(default_factory=list)
    #: the camera's rays are parallel (orthographic): the geometric outputs' planar depth is the ray length
    parallel_rays: bool = False


@dataclass
class MitsubaContext(TranslationContext):
    """One translation's state: the scene, the shapes built so far and what the handlers recorded."""

    scene: Any = None
    entries: dict[str, Any] = field(default_factory=dict)  # the renderables' scene-dictionary entries
    shapes: dict[str, ShapeInfo] = field(default_factory=dict)
    catchers: list[int] = field(default_factory=list)
    n_analytic_spheres: int = 0
    #: null light surfaces a ray may cross to pass through one light (0 none; 1 area lights; 2 the spheres
    #: of point lights with a radius)
    null_light_surfaces: int = 0
    #: some light is a shape the camera could meet (point-light sphere, area light, sun disk)
    light_shapes: bool = False
    #: ids of light-shape dictionaries no camera ray can reach (a sun's disk beyond the far clip)
    unreachable_lights: set[int] = field(default_factory=set)
    #: the distinct layered BSDFs (their specs) this scene has (see LAYERED_MAX_DISTINCT)
    layered_specs: set[str] = field(default_factory=set)
    bounds: Any = None  # the scene bounds (for point lights with a radius)
    aniso: SquarePixelPlan | None = None
    parallel_rays: bool = False  # set by the camera handler
    #: emitter ids of the lights that cast no shadow (rendered by the integrator 'blendify_path')
    no_shadow: list[str] = field(default_factory=list)
    #: some surface has alpha < 1 (a ``mask`` BSDF): light passes through it to the surfaces behind, so
    #: shadow rays must too (Cycles' transparent shadows; see MitsubaTranslator.integrator)
    masked: bool = False
    #: emitters (lights, the world) and, of them, the light shapes other than sun disks (point-light spheres,
    #: area lights): null surfaces that Mitsuba's ``path`` lets block the shadow rays of the other emitters
    n_emitters: int = 0
    blocking_light_shapes: int = 0


# ---------------------------------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------------------------------


def _mat(m: np.ndarray) -> Any:
    return _mi().ScalarTransform4f(np.asarray(m, dtype=np.float64).tolist())


def _rgb(c: Any) -> dict[str, Any]:
    return {"type": "rgb", "value": [float(x) for x in np.asarray(c, dtype=np.float64)[:3]]}


def _world(vertices: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    return np.asarray(vertices, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


def camera_to_world_cv(camera: Any) -> np.ndarray:
    """``T_cv``: 4x4 camera-to-world of the OpenCV camera frame."""
    r, t = camera.opencv_extrinsics()
    m = np.eye(4)
    m[:3, :3] = r.T
    m[:3, 3] = -r.T @ t
    return m


def _effective_eta(ior: float, level: float) -> float:
    """Blender's "Specular IOR Level" scales F0 by 2 * level; return the IOR with that F0."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level
    f0 = min(max(f0, 1e-6), 0.99)
    s = math.sqrt(f0)
    return (1.0 + s) / (1.0 - s)


def _data_texture(values: np.ndarray) -> dict[str, Any]:
    """A raw (never colour-managed) single-channel bitmap; UVs are v-flipped like colour textures."""
    data = np.ascontiguousarray(np.asarray(values, dtype=np.float32)[..., None])
    return {"type": "bitmap", "data": _mi().TensorXf(data), "raw": True, "filter_type": "bilinear"}


#: Mitsuba's spot texture spans tan(angle) / tan(cutoff): beyond this half-angle the blend band would be
#: squeezed into too few texels (and tan(90 deg) overflows), so wider spots keep Mitsuba's linear ramp
_SPOT_TEXTURE_MAX_HALF = math.radians(88.0)
#: largest spot falloff texture (per side) and the interpolation error it must reach
_SPOT_TEXTURE_MAX_RES = 1024
_SPOT_TEXTURE_TOL = 5e-3


def _spot_texture(spot_size: float, spot_blend: float) -> dict[str, Any] | None:
    """Blender's spot falloff (:func:`blendify_core.ir.physics.spot_falloff`) as the texture Mitsuba's ``spot``
    projects over its cone: the texel at uv looks along tan(angle) = 2 |uv - 0.5| tan(cutoff) (Mitsuba's
    ``spot``: uv = 0.5 + 0.5 (x / z) / tan(cutoff)), radially symmetric so the v flip is moot. The size is the
    smallest power of two whose bilinear interpolation along a radius stays within ``_SPOT_TEXTURE_TOL``;
    None when the cone is too wide or no size up to ``_SPOT_TEXTURE_MAX_RES`` is fine enough."""
    half = 0.5 * float(spot_size)
    if half > _SPOT_TEXTURE_MAX_HALF:
        return None
    tan_half = math.tan(half)

    def falloff(r: np.ndarray) -> np.ndarray:  # r: distance from the texture's centre in uv
        tan = 2.0 * r * tan_half
        return spot_falloff(1.0 / np.sqrt(1.0 + tan * tan), spot_size, spot_blend)

    n = 64
    while True:
        centres = (np.arange(n // 2) + 0.5) / n  # texel centres along a radius
        fine = np.linspace(0.0, 0.5, 16 * n)  # to the cone's edge: beyond the last centre Mitsuba clamps
        if np.max(np.abs(np.interp(fine, centres, falloff(centres)) - falloff(fine))) <= _SPOT_TEXTURE_TOL:
            break
        if n >= _SPOT_TEXTURE_MAX_RES:
            return None
        n *= 2
    c = (np.arange(n) + 0.5) / n - 0.5
    r = np.hypot(c[:, None], c[None, :])
    return _data_texture(falloff(r)) | {"wrap_mode": "clamp"}


def _normal_texture(nmap: Any) -> dict[str, Any]:
    """The tangent-space normal map for Mitsuba's ``normalmap`` BSDF, with Blender's ``strength`` baked in
    (:func:`blendify_core.ir.physics.blend_normal_map`). Mitsuba's shading frame is (dp/du, n x dp/du),
    Blender's tangent frame for UVs of the usual orientation; the v -> 1 - v flip of the UVs does not change
    dp/du."""
    n = blend_normal_map(nmap.normals(), float(nmap.strength))
    data = np.ascontiguousarray(((n + 1.0) * 0.5).astype(np.float32))
    return {"type": "bitmap", "data": _mi().TensorXf(data), "raw": True, "filter_type": "bilinear"}


def _with_normal_map(inner: dict[str, Any], material: Any) -> dict[str, Any]:
    """``inner`` under the material's normal map (if it has one)."""
    if material.normal_map is None:
        return inner
    return {"type": "normalmap", "normalmap": _normal_texture(material.normal_map), "bsdf": inner}


def _constant_rgb(color: Any) -> np.ndarray | None:
    """The linear RGB (3,) of a constant Mitsuba colour made by :func:`_rgb`, else None (a texture)."""
    if isinstance(color, dict) and color.get("type") == "rgb":
        return np.asarray(color["value"], dtype=np.float64)
    return None


def _emission(material: Any) -> np.ndarray | None:
    """The emitted radiance (3,) of an emissive material, or None."""
    if not material.is_emissive:
        return None
    return material.linear("emission_color")[:3] * float(material.emission_strength)


def _size_ratio(ctx: Any, centres: np.ndarray, radii: np.ndarray) -> float:
    """The smallest radius over the scene's extent seen from the points: the largest distance from the camera
    to the points' bounding box, or the largest coordinate (the float32 spacing of either limits Embree's
    curves)."""
    cam = np.asarray(ctx.scene.camera.translation, dtype=np.float64)
    lo, hi = centres.min(axis=0), centres.max(axis=0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    far = max(float(np.linalg.norm(corners - cam, axis=1).max()), float(np.abs(corners).max()))
    return float(np.min(radii)) / far if far > 0 else float("inf")


#: a sun's disk lies this many scene radii away (:meth:`MitsubaTranslator._sun_disk`) ...
SUN_DISK_DISTANCE = 1e4
#: ... but at most this many metres (float32 precision of Mitsuba's emitter sampling) ...
SUN_DISK_MAX_DISTANCE = 2e5
#: ... and at least this many scene radii (else the sun stays a delta light)
SUN_DISK_MIN_DISTANCE = 1e3


#: a smooth mesh renders with Cycles' sidedness rule (blendify_sided) when more than LEAN_AREA_FRACTION of
#: its area lies on triangles with a corner normal leaning more than LEAN_DEGREES from the face: low-poly
#: smooth meshes (a smooth box: all of it; an icosahedron: all) but not scans (the bunny test mesh: 5 %,
#: where the two rules gave the same image mean) nor the primitives' fine tessellations (0 %)
LEAN_DEGREES = 30.0
LEAN_AREA_FRACTION = 0.2


def _with_mask(ctx: MitsubaContext, bsdf: dict[str, Any], opacity: Any, needed: bool) -> dict[str, Any]:
    """``bsdf`` wrapped in a ``mask`` of ``opacity`` when ``needed`` (alpha < 1 somewhere); records in
    ``ctx.masked`` that the scene has such a surface (its shadows are then transparent too)."""
    if not needed:
        return bsdf
    ctx.masked = True
    return {"type": "mask", "opacity": opacity, "bsdf": bsdf}


def blender_rows_for_mitsuba(img: np.ndarray) -> np.ndarray:
    """An equirectangular image (H rows) resampled so that Mitsuba's ``envmap`` shows what Blender shows.

    Blender places row r at v = (r + 1/2) / H and interpolates linearly between row centres (the first and
    last rows hold to the poles); Mitsuba 3.9 places the rows of its bitmap at v = k / (rows - 1), the
    first on the north pole and the last on the south pole (measured: a single bright texel of a 16-row map
    peaked 0.2 rows off and spread over 2.13 rows). Given 2H + 1 rows at v = k / (2H) -- Blender's row
    centres at odd k, the midpoints between them at even k, the end rows at the poles -- Mitsuba's linear
    interpolation reproduces Blender's exactly (columns already agree: centre-aligned, wrapping). Before, a
    single bright texel of a 16-row map lit a plane 0.80x (near the zenith) to 1.20x (near the horizon) as
    much as in Cycles."""
    h = img.shape[0]
    out = np.empty((2 * h + 1, *img.shape[1:]), dtype=np.float32)
    out[1::2] = img
    out[2:-1:2] = 0.5 * (img[:-1] + img[1:])
    out[0], out[-1] = img[0], img[-1]
    return np.ascontiguousarray(out)


def build_curves(name: str, centres: np.ndarray, radii: np.ndarray, bsdf: Any, axis: Any) -> Any:
    """One ``linearcurve`` shape of spheres, their segments along ``axis``
    (:func:`blendify_mitsuba.points.curve_points`)."""
    mi = _mi()
    if hasattr(mi, "build_curves"):  # the exporter's stand-in engine keeps the points
        return mi.build_curves(name, centres, radii, bsdf, axis)
    return curve_points(centres, radii, bsdf, axis)


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
    mi = _mi()
    if hasattr(mi, "build_mesh"):  # the exporter's stand-in engine keeps the buffers
        return mi.build_mesh(name, vertices, faces, normals, uv, attributes, bsdf, emitter)
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


# ---------------------------------------------------------------------------------------------------
# colour sources: what the colour handlers return
# ---------------------------------------------------------------------------------------------------


@dataclass
class ColorSource:
    """A colour source as Mitsuba sees it (built by the colour handlers).

    ``constant``: (4,) linear RGBA of a uniform colour, else None; ``per_vertex``: (N, 4) linear RGBA per
    vertex or point, else None; ``needs_uv``: a texture (the mesh needs a UV map)."""

    constant: np.ndarray | None = None
    per_vertex: np.ndarray | None = None
    has_alpha: bool = False
    needs_uv: bool = False
    texture: Any = None  # TextureColors / FileTextureColors
    file_path: str | None = None  # a file Mitsuba may read itself

    def reflectance(self) -> tuple[Any, np.ndarray | None, Any]:
        """(Mitsuba reflectance value/texture, constant albedo or None, evaluable texture or None)."""
        if self.constant is not None:
            c = self.constant[:3]
            return _rgb(c), c, None
        mi = _mi()
        if self.per_vertex is not None:
            tex = mi.load_dict({"type": "mesh_attribute", "name": "vertex_color"})
            return tex, None, tex
        tex = mi.load_dict(_texture_dict(self.texture, "rgb", self.file_path))
        return tex, None, tex

    def opacity(self, alpha: float) -> tuple[Any, bool]:
        """Opacity value or texture for a ``mask`` wrapper (material ``alpha`` x colour alpha), and whether
        one is needed."""
        if self.constant is not None:
            a = alpha * float(self.constant[3])
            return a, a < 1.0
        if self.per_vertex is not None and self.has_alpha:
            return {"type": "mesh_attribute", "name": "vertex_alpha", "scale": alpha}, True
        if self.texture is not None and self.has_alpha:
            d = _texture_dict(self.texture, "alpha")
            if alpha < 1.0:
                data = np.array(d["data"]) * np.float32(alpha)
                d["data"] = _mi().TensorXf(data.astype(np.float32))
            return d, True
        return alpha, alpha < 1.0

    def vertex_attributes(self, source: np.ndarray) -> dict[str, np.ndarray]:
        """Mesh attributes for the mesh vertices taken from the renderable's vertices ``source``."""
        if self.per_vertex is None:
            return {}
        rgba = self.per_vertex[source]
        attrs = {"vertex_color": rgba[:, :3]}
        if self.has_alpha:
            attrs["vertex_alpha"] = rgba[:, 3]
        return attrs


def _texture_dict(colors: Any, channel: str = "rgb", file_path: str | None = None) -> dict[str, Any]:
    """A ``bitmap`` for texture colours (``channel`` "rgb" or "alpha"); ``file_path``: the colours' file,
    which Mitsuba reads itself when it decodes it as the IR does."""
    mi = _mi()
    filt = "nearest" if colors.interpolation == "closest" else "bilinear"
    raw_img = colors.image()
    srgb_bytes = raw_img.dtype == np.uint8 and colors.color_space == "srgb"
    if channel == "rgb" and file_path is not None and (filt == "nearest" or not srgb_bytes):
        suffix = Path(file_path).suffix.lower()
        if suffix in (".png", ".jpg", ".jpeg") and raw_img.dtype == np.uint8:
            # Mitsuba decodes 8-bit sRGB itself unless raw=True (same meaning as the IR's colour space)
            return {
                "type": "bitmap",
                "filename": file_path,
                "raw": colors.color_space == "linear",
                "filter_type": filt,
            }
    if channel == "rgb" and filt == "bilinear" and srgb_bytes:
        h, w = raw_img.shape[:2]
        k = int(max(1, min(8, math.floor(math.sqrt(SRGB_UPSAMPLE_MAX_TEXELS / (h * w))))))
        if k > 1:
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


# ---------------------------------------------------------------------------------------------------
# geometry helpers
# ---------------------------------------------------------------------------------------------------


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


#: the wire bands' lift over their triangle, relative to 1 + the largest coordinate: a quarter of Mitsuba's
#: ray offset (``RayEpsilon`` = 1500 * 2^-24 of the same scale), about 180 float steps
WIRE_LIFT = 0.25 * 1500.0 * 2.0**-24


def wire_bands(vertices: np.ndarray, faces: np.ndarray, thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """The points Cycles' Wireframe shader marks, as geometry: inside every triangle, a band of width
    ``thickness / 2`` along each of its edges (the neighbour draws the other half, so an edge's line is
    ``thickness`` wide), in the triangle's plane lifted along its normal by :data:`WIRE_LIFT` of the
    coordinates' scale (at most 2 % of the thickness):
    (V, 3) vertices and (F, 3) triangles. Flat, so it neither protrudes nor casts shadows; every triangle
    edge is drawn, the diagonals of triangulated polygons too (as Cycles does)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    normal = np.cross(b - a, c - a)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    p0, p1, opposite = np.concatenate([a, b, c]), np.concatenate([b, c, a]), np.concatenate([c, a, b])
    n = np.concatenate([normal, normal, normal])
    axis = p1 - p0
    length = np.linalg.norm(axis, axis=1)
    ok = (length > 0) & (np.linalg.norm(n, axis=1) > 0.5)
    p0, p1, opposite, axis, length, n = p0[ok], p1[ok], opposite[ok], axis[ok], length[ok], n[ok]
    axis /= length[:, None]
    inward = np.cross(n, axis)
    inward *= np.where(np.einsum("ij,ij->i", opposite - p0, inward) < 0, -1.0, 1.0)[:, None]
    # below the offset Mitsuba gives rays leaving the surface underneath ((1 + max |p|) RayEpsilon along the
    # normal), so the bands never shadow it (lifted by 2 % of the thickness they did: the wireframe presets
    # of the material sweep were 6-8 % darker than Cycles), and far above float precision there
    reach = 1.0 + np.abs(np.stack([a, b, c], axis=1)).max(axis=(1, 2))
    reach = np.concatenate([reach, reach, reach])[ok]
    lift = n * np.minimum(0.02 * thickness, WIRE_LIFT * reach)[:, None]
    width = inward * (thickness / 2.0)
    seam = -0.05 * width  # the two bands of an edge overlap a little, so no ray slips between them
    verts = np.stack([p0 + seam + lift, p1 + seam + lift, p1 + width + lift, p0 + width + lift], axis=1)
    quads = np.array([[0, 1, 2], [0, 2, 3]])
    tris = quads[None] + (4 * np.arange(len(p0)))[:, None, None]
    return verts.reshape(-1, 3), tris.reshape(-1, 3)


def _coplanar_emitters(light: AreaLight, scene: Any) -> list[str]:
    """Tags of the emissive renderables with triangles in the plane of area light ``light`` that overlap its
    extent (bounding boxes in the light's plane): a difference by design between Mitsuba, where the light is a
    null surface coinciding with the emitter, and Cycles."""
    if scene is None:
        return []
    m = light.matrix_world
    c, ex, ey, n = m[:3, 3], m[:3, 0], m[:3, 1], m[:3, 2]
    half_a, half_b = light.size[0] / 2.0, light.size[1] / 2.0
    tol = 1e-6 * max(1.0, float(np.abs(c).max())) + 1e-4 * max(half_a, half_b)
    out = []
    for r in scene.renderables:
        if isinstance(r, PointCloud) or not any(mat.is_emissive for mat in r.materials):
            continue
        tm = r.to_mesh()
        if tm.is_empty:
            continue
        v = _world(tm.vertices, r.matrix_world)
        on_plane = np.abs((v - c) @ n) <= tol
        faces = np.asarray(tm.faces)[on_plane[tm.faces].all(axis=1)]
        if len(faces) == 0:
            continue
        p = v[np.unique(faces)] - c
        x, y = p @ ex, p @ ey
        if x.min() <= half_a and x.max() >= -half_a and y.min() <= half_b and y.max() >= -half_b:
            out.append(r.tag)
    return out


# ---------------------------------------------------------------------------------------------------
# the translator
# ---------------------------------------------------------------------------------------------------

_IR_TESSELLATION = _exact("IR tessellation")


#: standard deviation of Cycles' pixel filters in pixels per pixel of ``pixel_filter_width``: Cycles'
#: Gaussian is exp(-8 x^2 / w^2) (sigma w/4), its Blackman-Harris window spans [-w, w] (sigma 0.277 w)
_FILTER_SIGMA = {"gaussian": 0.25, "blackman_harris": 0.277}


def pixel_filter(settings: RenderSettings) -> dict[str, Any]:
    """Mitsuba's reconstruction filter for ``settings.pixel_filter``: the box as it is; Gaussian and
    Blackman-Harris as a Gaussian of Cycles' filter's standard deviation (Mitsuba has no Blackman-Harris)."""
    if settings.pixel_filter == "box":
        return {"type": "box"}
    return {"type": "gaussian", "stddev": _FILTER_SIGMA[settings.pixel_filter] * settings.pixel_filter_width}


class MitsubaTranslator(Translator):
    """The IR as a Mitsuba scene dictionary: one handler per IR type, capabilities declared beside them.

    ``settings`` give the film (pixel filter), the samples and the integrator; ``max_analytic_spheres``
    the largest point cloud made of analytic spheres, ``max_analytic_opaque`` (None: the same) the largest
    one that could be one curve shape of spheres (:func:`~blendify_mitsuba.points.curves_fit`); ``sampler``
    Mitsuba's sampler plugin."""

    backend = "mitsuba"

    #: features not tied to one IR type: the geometric outputs come from pixel-centre ray casts
    #: (blendify_mitsuba.render); per-object and per-light shadow switches are refused
    extra_capabilities = {
        "object.no_shadow": unsupported("Mitsuba has no per-object shadow visibility"),  # refused in translate()
        "light.no_shadow": _exact(
            "integrator 'blendify_path' (blendify_mitsuba.integrator): Mitsuba's path tracer with no visibility "
            "test for these lights' emitter samples; runs in Python, used only in scenes with such lights"
        ),
        "output.rgb": EXACT,
        "output.depth": _exact("planar z from pixel-centre ray casts"),
        "output.normal": _exact("world shading normal (facing the camera) from pixel-centre ray casts"),
        "output.albedo": _exact("the material colour input at the pixel centre"),
        "output.instance": _exact("renderable index from pixel-centre ray casts"),
    }

    def __init__(
        self,
        settings: RenderSettings | None = None,
        *,
        max_analytic_spheres: int = 100_000,
        max_analytic_opaque: int | None = None,
        sampler: str = DEFAULT_SAMPLER,
    ) -> None:
        self.settings = resolve_settings() if settings is None else settings
        self.max_analytic_spheres = int(max_analytic_spheres)
        opaque = self.max_analytic_spheres if max_analytic_opaque is None else max_analytic_opaque
        self.max_analytic_opaque = int(opaque)
        self.sampler = sampler

    # -- the walk ---------------------------------------------------------------------------------------
    def translate(self, scene: Any) -> Translation:
        """The ``mi.load_dict`` dictionaries of ``scene`` (and of the compositing/catcher passes it needs)."""
        ctx = MitsubaContext(scene=scene)
        effects = analyse_effects(scene)
        sensor = self.sensor(ctx)
        for ri, r in enumerate(scene.renderables):
            if not r.emit_shadows:
                raise UnsupportedFeatureError(
                    f"renderable {r.tag!r}: emit_shadows=False has no Mitsuba equivalent",
                    feature="object.no_shadow",
                    backend="mitsuba",
                )
            self.dispatch(r, ctx, ri)
        emitters = self.emitters(ctx)
        for attachment in scene.attachments:
            self.dispatch(attachment, ctx)
        integrator = self.integrator(effects, ctx)
        d: dict[str, Any] = {"type": "scene", "integrator": integrator, "sensor": sensor, **ctx.entries, **emitters}
        # lights are not seen by camera rays (as in Cycles): hide_emitters hides them, else the render removes
        # the emission of these shapes where camera rays meet them first
        hidden = integrator["hide_emitters"]
        light_shapes = (
            []
            if hidden
            else [
                k
                for k, e in emitters.items()
                if k.startswith("light") and "emitter" in e and id(e) not in ctx.unreachable_lights
            ]
        )
        sky = {k: v for k, v in d.items() if k in ("environment", "background")}

        coverage_dict = background_dict = None
        composite = bool(self.settings.transparent_background) and effects.emission
        if sky and (composite or (hidden and not self.settings.transparent_background)):
            # the sky alone: what it adds behind partly covered pixels; removed again for transparent films
            # with emissive surfaces, added back where an opaque film's hidden emitters left it out
            one = {"type": "path", "max_depth": 1, "hide_emitters": False}
            sky_dict = {k: (self._environment_again(ctx) if k == "environment" else v) for k, v in sky.items()}
            background_dict = {"type": "scene", "integrator": one, "sensor": self.sensor(ctx), **sky_dict}
        sky_radiance = None
        if background_dict is not None and list(sky) == ["background"]:
            sky_radiance = [float(x) for x in sky["background"]["radiance"]["value"]]
        if composite and sky:
            # max_depth 2: Mitsuba's path integrator records a hit in the alpha only once it decides to continue
            # the path (with max_depth 1 only emitters count); the scene has no lights, so this stays cheap
            two = {"type": "path", "max_depth": 2, "hide_emitters": False}
            coverage_dict = {"type": "scene", "integrator": two, "sensor": self.sensor(ctx), **ctx.entries}
        catcher_dict = objects_dict = None
        if ctx.catchers:
            # the catchers alone under the same lights: the unshadowed radiance of the shadow-catcher emulation
            own = tuple(f"r{ri:05d}_" for ri in ctx.catchers)
            catcher_dict = {k: v for k, v in d.items() if not k.startswith("r") or k.startswith(own)}
            if "environment" in catcher_dict:
                catcher_dict["environment"] = self._environment_again(ctx)
            catcher_dict["sensor"] = self.sensor(ctx)
            objects_dict = {k: v for k, v in d.items() if not k.startswith(own)}
            if "environment" in objects_dict:
                objects_dict["environment"] = self._environment_again(ctx)
            objects_dict["sensor"] = self.sensor(ctx)
        return Translation(
            d,
            ctx.shapes,
            ctx.n_analytic_spheres,
            coverage_dict=coverage_dict,
            background_dict=background_dict,
            sky_radiance=sky_radiance,
            catcher_dict=catcher_dict,
            catchers=ctx.catchers,
            objects_dict=objects_dict,
            light_shapes=light_shapes,
            integrator=integrator,
            effects=effects,
            spp=ctx.aniso.spp if ctx.aniso is not None else int(self.settings.samples),
            aniso=ctx.aniso,
            ignored=ctx.ignored,
            approximations=ctx.approximations,
            parallel_rays=ctx.parallel_rays,
        )

    def integrator(self, effects: Effects, ctx: MitsubaContext) -> dict[str, Any]:
        """The integrator dictionary: ``path`` (``volpath`` when a surface has alpha < 1: transparent
        shadows) with max_depth = max_bounces + 2, or max_depth 2 (direct
        light only; 3 when a camera ray may have to pass through a light's null surface, 4 through a visible
        point light's sphere) when ``settings.effects`` and the effect analysis finds no indirect light; and
        whether it hides the emitters from the camera; ``blendify_path`` when a light casts no shadow or
        ``settings.caustics`` is False. Call after the lights."""
        s = self.settings
        # Lights are not seen by camera rays, as in Cycles. hide_emitters hides the light shapes (and gives a
        # coverage alpha under a sky), but in Mitsuba 3.9 camera rays then pass through every emitter: the sky
        # and emissive *surfaces* vanish too. So it is used for transparent films and, when there are light
        # shapes, opaque ones (the render adds the sky back behind uncovered pixels), and never with emissive
        # materials: then the render removes the light shapes' directly seen emission instead
        # (Translation.light_shapes) and recovers a transparent film's alpha by compositing (see translate)
        hide = (bool(s.transparent_background) or ctx.light_shapes) and not effects.emission
        max_depth = s.max_bounces + 2
        if s.effects and not (effects.indirect_diffuse or effects.glossy or effects.transmission or effects.caustics):
            # direct light only; a visible light's surfaces crossed by a camera ray count as bounces
            crossings = min(ctx.null_light_surfaces, 1) if hide else ctx.null_light_surfaces
            max_depth = min(max_depth, 2 + crossings)
        # caustics=False (the target_error pilot's choice, or the user's): Mitsuba's path has no such switch,
        # blendify_path drops the glossy and refractive lobes at vertices reached by a diffuse bounce
        no_caustics = not s.caustics and effects.caustics
        # shadow rays must cross null surfaces: alpha < 1 (Cycles' transparent shadows), and the shapes of
        # lights, which in Cycles block no other light (with Mitsuba's path a spot inside a point light's
        # sphere kept 0.64 of its light, 26 mixed lights 1.06x the sum of their own renders)
        blockers = ctx.blocking_light_shapes > 0 and (ctx.n_emitters > 1 or effects.emission)
        crossing = ctx.masked or blockers
        if ctx.no_shadow or no_caustics:
            out: dict[str, Any] = {
                "type": register_integrator(),
                "max_depth": int(max_depth),
                "hide_emitters": hide,
                # shadow rays cross surfaces with alpha < 1 (as many as Cycles' transparent bounces); letting
                # them cross light shapes here too made 26 mixed lights 1.31x their sum (1.15x without): not done
                "transparent_shadows": s.bounces("transparent") if ctx.masked else 0,
            }
            if ctx.no_shadow:
                out["no_shadow"] = ",".join(ctx.no_shadow)
            if no_caustics:
                out["no_caustics"] = True
            return out
        # Mitsuba's ``path`` treats every surface as opaque to shadow rays, so a 30 % alpha plane cast a full
        # shadow where Cycles lets 70 % of the light through; ``volpath`` multiplies the shadow ray by the
        # null transmission of the surfaces it crosses (the ``mask``'s 1 - opacity, a light shape's 1) and
        # renders the same surfaces otherwise (no media in these scenes): used only where it matters
        kind = "volpath" if crossing else "path"
        return {"type": kind, "max_depth": int(max_depth), "hide_emitters": hide}

    def emitters(self, ctx: MitsubaContext) -> dict[str, Any]:
        """The emitters of the positioned lights (``light{i:04d}``), then of the world."""
        out: dict[str, Any] = {}
        ctx.bounds = ctx.scene.bounds()
        for i, light in enumerate(ctx.scene.lights):
            emitter = self.dispatch(light, ctx)
            if emitter is not None:
                key = f"light{i:04d}"
                out[key] = emitter
                ctx.light_shapes = ctx.light_shapes or (
                    "emitter" in emitter and id(emitter) not in ctx.unreachable_lights
                )
                ctx.n_emitters += 1
                ctx.blocking_light_shapes += "emitter" in emitter and not isinstance(light, SunLight)
                if not light.use_shadow:  # the integrator finds the emitter by its id
                    if "emitter" in emitter:  # a shape's area emitter
                        emitter["emitter"]["id"] = key = f"{key}_emitter"
                    ctx.no_shadow.append(key)
        world = self.world(ctx)
        ctx.n_emitters += len(world)
        out.update(world)
        return out

    def sensor(self, ctx: MitsubaContext) -> dict[str, Any]:
        """The sensor of the scene's camera (a fresh dictionary at every call)."""
        return self.dispatch(ctx.scene.camera, ctx)  # type: ignore[no-any-return]

    def world(self, ctx: MitsubaContext) -> dict[str, Any]:
        """The background light and the environment map. Mitsuba takes one environment emitter: a
        background light is added to the map (as Cycles adds the two Background shaders)."""
        lights = ctx.scene.lights
        bg = None if lights.background is None else self.dispatch(lights.background, ctx)
        env = None if lights.environment is None else self.dispatch(lights.environment, ctx)
        if env is not None:
            return {"environment": env}
        if bg is not None:
            return {"background": bg}
        return {}

    def _environment_again(self, ctx: MitsubaContext) -> dict[str, Any]:
        """A second envmap for another scene of the same translation (emitters are not shared)."""
        return self.dispatch(ctx.scene.lights.environment, ctx)  # type: ignore[no-any-return]

    # -- cameras ----------------------------------------------------------------------------------------
    def _film(self, camera: Any) -> dict[str, Any]:
        return {
            "type": "hdrfilm",
            "width": int(camera.width),
            "height": int(camera.height),
            "pixel_format": "rgba",
            "rfilter": pixel_filter(self.settings),
        }

    def _sampler(self, ctx: MitsubaContext) -> dict[str, Any]:
        spp = ctx.aniso.spp if ctx.aniso is not None else int(self.settings.samples)
        return {"type": self.sampler, "sample_count": spp}

    @handles(
        PerspectiveCamera,
        features={
            "camera.perspective": _exact("perspective sensor with principal-point offsets"),
            "camera.anisotropic": approximate(
                "fx != fy: colour rendered by a square-pixel camera (columns supersampled k <= 4 times, rows at "
                "k fx/fy per pixel, same samples per target pixel) and box-resampled with exact row overlaps (only "
                "boundary rows split); depth/normal/albedo/instance exact (cast through the target pixel centres)"
            ),
        },
    )
    def perspective_camera(self, camera: PerspectiveCamera, ctx: MitsubaContext) -> dict[str, Any]:
        """A pinhole sensor. Mitsuba's pixels are square: for fx != fy the sensor is the square-pixel camera
        of :func:`blendify_mitsuba.aniso.plan_square_pixels` (recorded in ``ctx.aniso``; the render resamples
        its image)."""
        if not math.isclose(camera.fx, camera.fy, rel_tol=1e-9):
            ctx.aniso = plan_square_pixels(camera, int(self.settings.samples))
            camera = ctx.aniso.camera
        w, h = camera.width, camera.height
        t_cv = camera_to_world_cv(camera)
        cxp, cyp = camera.cx + 0.5, camera.cy + 0.5
        return {
            "type": "perspective",
            "fov_axis": "x",
            "fov": math.degrees(2.0 * math.atan(w / (2.0 * camera.fx))),
            "principal_point_offset_x": (w / 2.0 - cxp) / w,
            "principal_point_offset_y": (h / 2.0 - cyp) / h,
            "near_clip": float(camera.near),
            "far_clip": float(camera.far),
            "to_world": _mat(t_cv @ MI_FROM_CV),
            "film": self._film(camera),
            "sampler": self._sampler(ctx),
        }

    @handles(
        OrthographicCamera,
        features={"camera.orthographic": _exact("orthographic sensor, principal point by translating the camera")},
    )
    def orthographic_camera(self, camera: OrthographicCamera, ctx: MitsubaContext) -> dict[str, Any]:
        """An orthographic sensor scaled to ``ortho_scale``; the principal point moves the camera."""
        ctx.parallel_rays = True
        w, h = camera.width, camera.height
        t_cv = camera_to_world_cv(camera)
        cxp, cyp = camera.cx + 0.5, camera.cy + 0.5
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
            "film": self._film(camera),
            "sampler": self._sampler(ctx),
        }

    # -- renderables ------------------------------------------------------------------------------------
    @handles(
        Mesh,
        features={
            "mesh": EXACT,
            "mesh.faces_material": _exact("one Mitsuba mesh per material slot"),
            "mesh.smooth": _exact("vertex normals"),
        },
    )
    def mesh(self, mesh: Mesh, ctx: MitsubaContext, index: int) -> None:
        """A triangle mesh: one ``mi.Mesh`` per material slot, from numpy buffers."""
        self._tessellated(mesh, ctx, index)

    @handles(
        CubeMesh,
        CircleMesh,
        CylinderMesh,
        EllipsoidNURBS,
        features={
            "primitive.cube": _IR_TESSELLATION,
            "primitive.circle": _IR_TESSELLATION,
            "primitive.cylinder": _IR_TESSELLATION,
            "primitive.ellipsoid": _IR_TESSELLATION,
        },
    )
    def tessellated_primitive(self, primitive: Any, ctx: MitsubaContext, index: int) -> None:
        """Mesh primitives and ellipsoids: the IR's tessellation."""
        self._tessellated(primitive, ctx, index)

    @handles(
        PlaneMesh,
        features={
            "primitive.plane": _IR_TESSELLATION,
            "shadow_catcher": approximate(
                "emulated from three renders (all, the catchers alone, all but the catchers): where a pixel "
                "centre sees the catcher (or the background beside the catcher only), black with alpha = 1 - "
                "shadowed/unshadowed luminance; the other pixels from the render without the catchers (a "
                "catcher neither lights nor shades the objects, as in Cycles), their alpha grown by the shadow "
                "beside them where they also cover a catcher"
            ),
        },
    )
    def plane(self, plane: PlaneMesh, ctx: MitsubaContext, index: int) -> None:
        """A plane: the IR's tessellation. A shadow catcher is recorded for the emulation (the catchers-alone
        and catcher-free scenes built by :meth:`translate`, composited by
        :func:`blendify_mitsuba.render.catch_shadows`)."""
        if plane.shadow_catcher:
            ctx.catchers.append(index)
        self._tessellated(plane, ctx, index)

    @handles(
        CurveBezier,
        features={
            "primitive.curve": _exact(
                "IR tessellation (tube along the polyline); its reflecting BSDFs decide the side by the geometric "
                "normal, as Cycles does (blendify_mitsuba/sided.py)"
            )
        },
    )
    def curve(self, curve: CurveBezier, ctx: MitsubaContext, index: int) -> None:
        """A curve: the IR's tube along the polyline, with Cycles' sidedness rule (:mod:`.sided`): its
        shading normals lean up to half a bend's angle off its faces, so the two engines' rules differ over
        large parts of a tube seen at a grazing angle."""
        self._tessellated(curve, ctx, index, geometric_sides=True)

    @handles(
        SphereNURBS,
        features={
            "primitive.sphere": _exact(
                "the IR's shared tessellation (64x32 UV sphere, exact vertex normals), as in Cycles and pyrender"
            )
        },
    )
    def sphere(self, sphere: SphereNURBS, ctx: MitsubaContext, index: int) -> None:
        """A sphere: the IR's tessellation, the surface Cycles and pyrender render (Mitsuba's analytic
        ``sphere`` would differ from it by up to 1.2e-3 of the radius in depth)."""
        self._tessellated(sphere, ctx, index)

    def _tessellated(self, r: Any, ctx: MitsubaContext, index: int, geometric_sides: bool = False) -> None:
        """Meshes, mesh primitives, ellipsoids and curves: the IR's tessellation in world space, one Mitsuba
        mesh per material slot, plus the wireframe tubes of wireframe materials. ``geometric_sides``: wrap
        reflecting BSDFs (no transmission, no alpha mask) in :data:`.sided.SIDED_BSDF` (Cycles' rule)."""
        mi = _mi()
        prefix = f"r{index:05d}"
        tm = r.to_mesh()
        if tm.is_empty:
            return
        if not geometric_sides and tm.smooth and tm.normals is not None:
            # smooth meshes whose normals lean far from their faces (a low-poly smooth box or cylinder) take
            # Cycles' sidedness rule too: with Mitsuba's a smooth box was 0.89x Cycles; finer meshes (the
            # bunny, the sphere primitives) differ only in sub-pixel bands and keep the cheaper rule
            lean = leaning_area_fraction(tm.vertices, tm.faces, tm.normals, LEAN_DEGREES)
            geometric_sides = lean > LEAN_AREA_FRACTION
        fm = getattr(r, "faces_material", None)  # meshes and mesh primitives: per-triangle slots
        parts = _split(tm, r.matrix_world, fm, len(r.materials))
        for k, (mat, colors, part) in enumerate(zip(r.materials, r.colors_list, parts, strict=True)):
            if part is None:
                continue
            key = f"{prefix}_m{k:03d}"
            src = self.dispatch(colors, ctx)
            refl, const, tex = src.reflectance()
            if src.needs_uv and part.uv is None:
                raise InvalidSceneError(f"renderable {r.tag!r}: texture colours need a UV map")
            opacity, masked = src.opacity(float(mat.alpha))
            bsdf_d = _with_mask(ctx, self.dispatch(mat, ctx, refl), opacity, masked)
            if geometric_sides and not masked and not material_lobes(mat).transmission:
                bsdf_d = {"type": register_sided(), "bsdf": mi.load_dict(bsdf_d)}
            bsdf = mi.load_dict(bsdf_d)
            em = _emission(mat)
            emitter = mi.load_dict({"type": "area", "radiance": _rgb(em)}) if em is not None else None
            attrs = src.vertex_attributes(part.source)
            ctx.entries[key] = build_mesh(key, part.vertices, part.faces, part.normals, part.uv, attrs, bsdf, emitter)
            ctx.shapes[key] = ShapeInfo(index, const, tex)
            if mat.has_wireframe:
                self._wireframe(ctx, f"{prefix}_w{k:03d}", index, mat, part)

    def _wireframe(self, ctx: MitsubaContext, key: str, index: int, material: Any, part: _Part) -> None:
        """The wireframe overlay as geometry: flat bands along the edges (:func:`wire_bands`), with the
        surface's BSDF in the wireframe colour (as the Cycles backend mixes a second Principled in that colour
        along the edges)."""
        thickness = float(material.wireframe_thickness)
        if thickness <= 0 or len(part.faces) == 0:
            return
        verts, tris = wire_bands(part.vertices, np.asarray(part.faces), thickness)
        if len(tris) == 0:
            return
        wire = material.linear("wireframe_color")
        bsdf_d = self.dispatch(material, ctx, _rgb(wire[:3]))
        if wire[3] < 1.0:
            bsdf_d = {"type": "mask", "opacity": float(wire[3]), "bsdf": bsdf_d}
        ctx.entries[key] = build_mesh(key, verts, tris, bsdf=_mi().load_dict(bsdf_d))
        ctx.shapes[key] = ShapeInfo(index, np.asarray(wire[:3], dtype=np.float64))

    @handles(
        PointCloud,
        features={
            "pointcloud": _exact(
                "analytic spheres up to max_analytic_opaque points for opaque, non-emissive clouds, beyond that "
                "one shape of exact spheres (Embree round curves, each point a segment ending in its sphere, "
                "per-point colours in a bitmap); other clouds analytic spheres up to max_analytic_spheres points, "
                "else the IR's merged icosphere mesh"
            ),
            "pointcloud.vertex_colors": EXACT,
            "pointcloud.emission": approximate("area emitter on the spheres, front (outer) side only"),
        },
    )
    def pointcloud(self, r: PointCloud, ctx: MitsubaContext, index: int) -> None:
        """Analytic spheres (one shape and BSDF per point) up to ``max_analytic_opaque`` points for opaque,
        non-emissive, non-transmissive clouds under a similarity transform, beyond that one ``linearcurve``
        shape of spheres (:mod:`blendify_mitsuba.points`); other clouds analytic spheres up to
        ``max_analytic_spheres`` points, beyond that one merged icosphere mesh with per-vertex colours."""
        mi = _mi()
        prefix = f"r{index:05d}"
        matrix = r.matrix_world
        mat = r.materials[0]
        src = self.dispatch(r.colors_list[0], ctx)
        centres = _world(r.vertices, matrix)
        radii = r.radii()
        n = len(centres)
        if n == 0:
            return
        per_point = src.per_vertex[:, :3] if src.per_vertex is not None else None
        uniform = None if per_point is not None else src.constant[:3]
        strength = r.particle_emission_strength
        alpha = float(mat.alpha)
        scale = float(np.linalg.svd(np.asarray(matrix)[:3, :3], compute_uv=False)[0])
        emissive = strength > 0 or _emission(mat) is not None
        size_ratio = _size_ratio(ctx, centres, radii * scale)
        curves = curves_fit(mat, src.opacity(alpha)[1], emissive, matrix, size_ratio) is None
        if n <= (self.max_analytic_opaque if curves else self.max_analytic_spheres):
            for i in range(n):
                c = per_point[i] if per_point is not None else uniform
                bsdf = self.dispatch(mat, ctx, _rgb(c))
                if per_point is not None:  # this point's alpha (linear RGBA: no decoding)
                    own = ColorSource(constant=np.array([1.0, 1.0, 1.0, float(src.per_vertex[i, 3])]))
                    bsdf = _with_mask(ctx, bsdf, *own.opacity(alpha))
                else:
                    bsdf = _with_mask(ctx, bsdf, *src.opacity(alpha))
                key = f"{prefix}_p{i:07d}"
                shape = {"type": "sphere", "center": centres[i].tolist(), "radius": float(radii[i]), "bsdf": bsdf}
                em = _emission(mat)
                if strength > 0:
                    em = (em if em is not None else 0.0) + np.asarray(c) * strength
                if em is not None:
                    shape["emitter"] = {"type": "area", "radiance": _rgb(em)}
                ctx.entries[key] = shape
                ctx.shapes[key] = ShapeInfo(index, np.asarray(c, dtype=np.float64))
            ctx.n_analytic_spheres += n
            return
        if curves:
            key = f"{prefix}_curves"
            if per_point is not None:
                tex = mi.load_dict(point_bitmap(per_point, mi.TensorXf))
                bsdf_d = self.dispatch(mat, ctx, tex)
                ctx.shapes[key] = ShapeInfo(index, None, tex)
            else:
                bsdf_d = self.dispatch(mat, ctx, _rgb(uniform))
                ctx.shapes[key] = ShapeInfo(index, np.asarray(uniform, dtype=np.float64))
            # segments across the view (the camera's right vector): camera rays never run along them
            axis = np.asarray(ctx.scene.camera.matrix_world, dtype=np.float64)[:3, 0]
            ctx.entries[key] = build_curves(key, centres, radii * scale, bsdf_d, axis)
            return
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
            if src.has_alpha:
                attrs["vertex_alpha"] = np.repeat(src.per_vertex[:, 3], nv)
            const, tex = None, refl
        else:
            refl, const, tex = _rgb(uniform), np.asarray(uniform, dtype=np.float64), None
        bsdf = mi.load_dict(_with_mask(ctx, self.dispatch(mat, ctx, refl), *src.opacity(alpha)))
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
        ctx.entries[key] = build_mesh(key, verts, tm.faces, normals, None, attrs, bsdf, emitter)
        ctx.shapes[key] = ShapeInfo(index, const, tex)

    # -- materials: the (two-sided) BSDF for a material and its colour value/texture ---------------------
    @handles(
        PrincipledBSDFMaterial,
        DiffuseMaterial,
        MetalMaterial,
        PlasticMaterial,
        PrincipledBSDFWireframeMaterial,
        PlasticWireframeMaterial,
        MetalWireframeMaterial,
        features={
            "material.principled": approximate(
                "uniform colours, isotropic: Cycles' layer model (docs/conventions.md). JIT variants: "
                "blendify_mitsuba/layered.py, a Dr.Jit BSDF with each GGX lobe's own Fresnel, height-correlated "
                "shadowing and Cycles' view-dependent layer weights (tables per viewing cosine), also for opaque "
                "materials with colour textures or vertex colours (the base colour evaluated per point); scalar_rgb "
                "and exported scene files: a sum of Mitsuba's built-in lobes (blendify_mitsuba/principled.py, each "
                "GGX lobe a roughconductor fitted to the albedo curve of Cycles' lobe) holding the cosine-weighted "
                "means of those weights (listed in meta['approximations']). Material sweep: "
                "benchmarks/results/material_sweep.md. Roughness/metallic maps, anisotropy, textured glass, and "
                "textures in scalar_rgb: Mitsuba 'principled' (Disney diffuse, Schlick Fresnel; 3-13 % off on "
                "dielectrics)"
            ),
            "material.diffuse_only": _exact("Lambertian 'diffuse' (matches Cycles within 0.1 %)"),
            "material.metallic": approximate(
                "JIT variants: Cycles' F82-tint Fresnel (blendify_mitsuba/layered.py); scalar_rgb: a roughconductor "
                "whose complex IOR is fitted to the albedo curve of Cycles' metal, scaled to its albedo (a dark "
                "specular tint 2-4 % off there: its dip at grazing angles has no conductor equivalent)"
            ),
            "material.transmission": approximate(
                "a solid (one-sided, relative IOR 'ior'), transmittance sqrt(base colour) per crossing, mixed with "
                "the opaque lobes by the layers' weight. JIT variants: rough GGX glass with Cycles' view-dependent "
                "multiple-scattering compensation on each side (blendify_mitsuba/layered.py); scalar_rgb: "
                "roughdielectric scaled so that a white glass sphere in a white furnace is as bright as Cycles' "
                "MULTI_GGX glass (measured table)"
            ),
            "material.coat": approximate(
                "a dielectric GGX lobe of coat_ior (as the specular layer) over the rest, which it attenuates"
            ),
            "material.sheen": approximate(
                "a broad GGX lobe scaled to Cycles' sheen albedo (measured with Cycles, "
                "benchmarks/measure_sheen_albedo.py; per viewing cosine in the JIT variants, a fitted roughconductor "
                "in scalar_rgb), attenuating the layers below: not the microfiber lobe"
            ),
            "material.subsurface": unsupported("Mitsuba has no subsurface scattering in the principled BSDF"),
            "material.roughness_map": approximate(
                "raw bitmap driving principled roughness (the principled BSDF's differences)"
            ),
            "material.metallic_map": approximate(
                "raw bitmap driving principled metallic (the principled BSDF's differences)"
            ),
            "material.normal_map": approximate(
                "Mitsuba 'normalmap' (frame dp/du, n x dp/du; strength baked into the map); not compared with "
                "Cycles yet"
            ),
            # applied where the shapes are built: _emission -> an area emitter, ColorSource.opacity -> a mask,
            # MitsubaTranslator._wireframe -> tubes (these hold for the Glossy BSDF's alpha too)
            "material.emission": approximate(
                "area emitter on the surface: emits from the front side only; with a background/environment light "
                "the coverage alpha is composited from two extra one-bounce passes"
            ),
            "material.alpha": _exact(
                "mask BSDF with the material x colour alpha; its shadows transparent as in Cycles (volpath, or "
                "blendify_path's shadow rays with shadowless lights)"
            ),
            "material.wireframe": approximate(
                "the points Blender's Wireframe shader marks (within wireframe_thickness / 2 of a triangle edge, "
                "world units) as flat bands on each triangle with the surface's BSDF in the wireframe colour, lifted "
                "less than Mitsuba's ray offset so that they cast no shadow on the surface beneath; flat-shaded "
                "(Cycles shades the wire with the surface's smooth normals). Material sweep: sphere mean within 0.5 %"
                " of Cycles"
            ),
        },
    )
    def principled(self, material: PrincipledBSDFMaterial, ctx: MitsubaContext, color: Any) -> dict[str, Any]:
        """The Principled family: Lambertian ``diffuse`` when the material has no specular layer (exact);
        with a uniform colour, no maps and no anisotropy Cycles' layer model as a sum of built-in lobes
        (:func:`blendify_mitsuba.principled.principled_bsdf`); else Mitsuba's ``principled`` with the maps as
        raw bitmaps. The normal map goes through ``normalmap``."""
        base = _constant_rgb(color)
        maps = material.roughness_map is not None or material.metallic_map is not None
        if base is not None and not maps and not material.is_diffuse_only and float(material.anisotropic) == 0:
            use_layered = _layered_variant()
            bsdf = principled_bsdf(material, base, lambda d: _with_normal_map(d, material), layered=use_layered)
            if use_layered and not _room_for_layered(ctx, bsdf):
                use_layered = False
                bsdf = principled_bsdf(material, base, lambda d: _with_normal_map(d, material))
            if use_layered:
                register_layered()
            elif ENGINE.get() is None and _layered_variant():
                ctx.approximate(
                    f"material.principled: beyond {LAYERED_MAX_DISTINCT} distinct Principled materials (e.g. "
                    "per-point colours) the rest are sums of Mitsuba's built-in lobes with the cosine-weighted "
                    "means of Cycles' view-dependent layer weights (each distinct layered BSDF costs about 65 ms "
                    "of tracing at the first render)"
                )
            elif ENGINE.get() is None:
                ctx.approximate(
                    "material.principled: in scalar_rgb Cycles' view-dependent layer weights become their "
                    "cosine-weighted means (the sum of Mitsuba's built-in lobes; the JIT variants render them "
                    "exactly with blendify_mitsuba.layered, which scalar_rgb would call once per sample)"
                )
            return dict(with_bitmaps(bsdf, _mi().Bitmap))
        if not maps and not material.is_diffuse_only and float(material.anisotropic) == 0:
            textured = self._layered_textured(material, color, ctx)
            if textured is not None:
                return textured
        if material.is_diffuse_only:
            inner: dict[str, Any] = {"type": "diffuse", "reflectance": color}
        else:
            rough: Any = float(material.roughness)
            metal: Any = float(material.metallic)
            if material.roughness_map is not None:
                rough = _data_texture(material.roughness_map.values())
            if material.metallic_map is not None:
                metal = _data_texture(material.metallic_map.values())
            eta = _effective_eta(float(material.ior), float(material.specular_ior))
            inner = {
                "type": "principled",
                "base_color": color,
                "metallic": metal,
                "roughness": rough,
                "eta": max(eta, 1.0001),
                "anisotropic": float(material.anisotropic),
                "spec_trans": float(material.transmission_weight),
                "clearcoat": float(material.coat_weight),
                "clearcoat_gloss": 1.0 - float(material.coat_roughness),
                "sheen": float(material.sheen_weight),
            }
        inner = _with_normal_map(inner, material)
        if float(material.transmission_weight) > 0:
            return inner  # transmission needs both sides to be distinct
        return {"type": "twosided", "bsdf": inner}

    @staticmethod
    def _layered_textured(material: PrincipledBSDFMaterial, color: Any, ctx: MitsubaContext) -> dict[str, Any] | None:
        """An opaque Principled material with a textured base colour (vertex colours, image textures) as the
        layered BSDF with ``color`` as its ``base_color`` (JIT variants only); None where that does not apply
        (transmission, mirror-like lobes, ``scalar_rgb``, export)."""
        if float(material.transmission_weight) > 0 or not _layered_variant():
            return None
        lay = layered_bsdf(principled_lobes(material, np.ones(3)), textured=True)
        if lay is None or not _room_for_layered(ctx, lay):
            return None
        register_layered()
        lay["base_color"] = color
        return {**_with_normal_map(lay, material)}

    @handles(
        GlossyBSDFMaterial,
        features={
            "material.glossy": approximate(
                "roughconductor with a perfect-mirror Fresnel tinted by the colour; for uniform colours scaled to "
                "Cycles' albedo (height-correlated shadowing, MULTI_GGX compensation)"
            )
        },
    )
    def glossy(self, material: GlossyBSDFMaterial, ctx: MitsubaContext, color: Any) -> dict[str, Any]:
        """Blender's Glossy BSDF: a (rough) conductor with a perfect-mirror Fresnel, tinted by the colour."""
        r = float(material.roughness)
        base = _constant_rgb(color)
        if base is not None:  # Cycles' shadowing and multiple-scattering energy, as an albedo scale
            color = with_bitmaps(raw_rgb(base * glossy_scale(r, material.distribution, base)), _mi().Bitmap)
        inner: dict[str, Any] = {"type": "conductor", "material": "none", "specular_reflectance": color}
        if r > 0:
            inner = {
                "type": "roughconductor",
                "material": "none",
                "distribution": "beckmann" if material.distribution == "BECKMANN" else "ggx",
                "alpha": max(r * r, 1e-4),
                "specular_reflectance": color,
            }
        return {"type": "twosided", "bsdf": inner}

    # -- colour sources ---------------------------------------------------------------------------------
    @handles(UniformColors)
    def uniform_colors(self, colors: UniformColors, ctx: MitsubaContext) -> ColorSource:
        """One linear RGB value (alpha through a ``mask``)."""
        return ColorSource(constant=colors.linear_rgba)

    @handles(
        VertexColors,
        features={"mesh.vertex_colors": _exact("mesh attribute 'vertex_color' (linear, interpolated like Cycles)")},
    )
    def vertex_colors(self, colors: VertexColors, ctx: MitsubaContext) -> ColorSource:
        """Per-vertex (per-point) colours: mesh attributes ``vertex_color`` and ``vertex_alpha``."""
        return ColorSource(per_vertex=colors.linear_rgba, has_alpha=colors.has_alpha)

    @handles(
        TextureColors,
        features={
            "mesh.texture": _exact(
                "in-memory bitmap, v -> 1 - v; 8-bit sRGB textures with linear interpolation are upsampled in "
                "encoded space (Cycles interpolates before decoding), up to 1M texels"
            )
        },
    )
    def texture_colors(self, colors: TextureColors, ctx: MitsubaContext) -> ColorSource:
        """An in-memory texture: a ``bitmap`` of linear data (see :data:`SRGB_UPSAMPLE_MAX_TEXELS`)."""
        return ColorSource(has_alpha=colors.has_alpha, needs_uv=True, texture=colors)

    @handles(
        FileTextureColors,
        features={
            "mesh.file_texture": _exact("read by Mitsuba (8-bit PNG/JPEG, nearest or linear data) or through the IR")
        },
    )
    def file_texture_colors(self, colors: FileTextureColors, ctx: MitsubaContext) -> ColorSource:
        """A texture file: read by Mitsuba when it decodes it as the IR does, else as in-memory data."""
        return ColorSource(has_alpha=colors.has_alpha, needs_uv=True, texture=colors, file_path=colors.texture_path)

    # -- lights (None: a light of strength 0 adds no emitter) ---------------------------------------------
    @handles(
        PointLight,
        features={
            "light.point": _exact("point, intensity = P / (4 pi)"),
            "light.point.soft": approximate(
                "point lights: a sphere emitter of radiance P / (4 pi^2 r^2) (Blender's sphere light with soft "
                "falloff off), hidden from the camera as light.area; spot lights: delta (radius ignored). The light's "
                "null surface also blocks other lights' shadow rays"
            ),
        },
    )
    def point_light(self, light: PointLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """A ``point`` emitter, or for a radius > 0 a ``sphere`` with a null BSDF and an area emitter."""
        if light.strength <= 0:
            return None
        col = light.linear_color
        r = float(light.shadow_soft_size)
        if r > 0:
            ctx.null_light_surfaces = 2  # in and out of the sphere
        if r > 0 and ctx.bounds is not None:
            # a sphere far from everything it lights (radius < 1e-3 of the distance) is a point light
            # to within 0.1 %; Mitsuba's float32 sphere-emitter sampling breaks down there (a 0.25 m
            # sphere 1 km away came out 1.9x too bright, 3 km away black)
            nearest = np.clip(light.translation, ctx.bounds[0], ctx.bounds[1])
            if r < 1e-3 * float(np.linalg.norm(light.translation - nearest)):
                r = 0.0
        if r > 0:
            # Blender's sphere light (soft falloff off): a sphere emitter of radiance P / (4 pi^2 r^2)
            return {
                "type": "sphere",
                "center": [float(x) for x in light.translation],
                "radius": r,
                "bsdf": {"type": "null"},
                "emitter": {"type": "area", "radiance": _rgb(col * sphere_light_radiance(light.strength, r))},
            }
        return {
            "type": "point",
            "intensity": _rgb(col * point_intensity(light.strength)),
            "position": [float(x) for x in light.translation],
        }

    @handles(
        SunLight,
        features={
            "light.sun": _exact("directional, irradiance = strength"),
            "light.sun.soft": _exact(
                "a distant disk emitter subtending the angular diameter, radiance = strength / (pi sin^2(d/2)), "
                f"{SUN_DISK_DISTANCE:g}x the scene's radius away (at most {SUN_DISK_MAX_DISTANCE:g} m), unseen by "
                "camera rays; scenes over "
                f"{SUN_DISK_MAX_DISTANCE / SUN_DISK_MIN_DISTANCE:g} m in radius keep a delta sun (listed in meta)"
            ),
        },
    )
    def sun_light(self, light: SunLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """A sun with an angular diameter: a distant disk (:meth:`_sun_disk`); without one (or in scenes too
        large for the disk), a ``directional`` emitter of irradiance = strength."""
        if light.strength <= 0:
            return None
        disk = self._sun_disk(light, ctx)
        if disk is not None:
            return disk
        return {
            "type": "directional",
            "irradiance": _rgb(light.linear_color * light.strength),
            "direction": [float(x) for x in light.direction],
        }

    def _sun_disk(self, light: SunLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """The sun as Cycles samples it: a disk of uniform radiance L subtending the angular diameter d, with
        L pi sin^2(d/2) = strength (the irradiance on a surface facing it), emitting towards the scene from
        :data:`SUN_DISK_DISTANCE` times the radius of the scene (renderables and camera) away, at most
        :data:`SUN_DISK_MAX_DISTANCE` m (Mitsuba's float32 emitter sampling lost 0.6 % of the light at 3e6 m,
        none at 3e5 m): its direction varies by at most 1e-4 rad across the scene (1e-3 rad for radii up to
        200 m), its irradiance by 2e-4. Camera rays do not see it (as Cycles' sun), reflections do: beyond the
        camera's far clip it is out of their reach (recorded in ``ctx.unreachable_lights``, so it needs no
        hiding), nearer it is a light shape hidden like the others. None: keep the delta sun (no angular
        diameter, no renderables, or a scene so large that the disk would come nearer than
        :data:`SUN_DISK_MIN_DISTANCE` radii: listed in meta)."""
        half = 0.5 * float(light.angular_diameter)
        if half <= 0 or ctx.bounds is None:
            return None
        lo, hi = ctx.bounds
        camera = ctx.scene.camera if ctx.scene is not None else None
        if camera is not None:
            lo, hi = np.minimum(lo, camera.translation), np.maximum(hi, camera.translation)
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
        dist = min(SUN_DISK_DISTANCE * radius, SUN_DISK_MAX_DISTANCE)
        if dist < SUN_DISK_MIN_DISTANCE * radius:
            ctx.approximate(
                f"light.sun.soft: sun {light.tag!r}: a delta directional light (hard shadows) in a scene of radius "
                f"{radius:.3g} m (the distant disk needs <= {SUN_DISK_MAX_DISTANCE / SUN_DISK_MIN_DISTANCE:g} m)"
            )
            return None
        d = np.asarray(light.direction, dtype=np.float64)
        helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        x = np.cross(helper, d)
        x /= np.linalg.norm(x)
        y = np.cross(d, x)
        r = dist * math.tan(half)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = x * r, y * r, d  # the disk's normal (+z: its emitting side) along d
        m[:3, 3] = centre - dist * d
        radiance = light.linear_color * (light.strength / (math.pi * math.sin(half) ** 2))
        disk = {
            "type": "disk",
            "to_world": _mat(m),
            "bsdf": {"type": "null"},
            "emitter": {"type": "area", "radiance": _rgb(radiance)},
        }
        # beyond the far clip (planar: a ray up to 84 deg off the axis reaches 10x it), camera rays never meet it
        if camera is None or 10.0 * camera.far < dist - radius:
            ctx.unreachable_lights.add(id(disk))
        return disk

    @handles(
        SpotLight,
        features={
            "light.spot": _exact("spot, intensity = P / (4 pi), cutoff = spot_size / 2"),
            "light.spot.blend": _exact(
                "Blender's smoothstep falloff as a projected texture (beam_width = cutoff; spots over "
                f"{2 * math.degrees(_SPOT_TEXTURE_MAX_HALF):.0f} deg or with blend bands too narrow for "
                f"{_SPOT_TEXTURE_MAX_RES} texels keep Mitsuba's linear ramp, listed in meta)"
            ),
        },
    )
    def spot_light(self, light: SpotLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """A ``spot`` emitter (delta: the radius is ignored) turned to emit along Blender's local -Z, its blend
        band a projected texture of :func:`blendify_core.ir.physics.spot_falloff` (see :func:`_spot_texture`)."""
        if light.strength <= 0:
            return None
        half, beam = spot_cone(light.spot_size, light.spot_blend)
        out = {
            "type": "spot",
            "intensity": _rgb(light.linear_color * point_intensity(light.strength)),
            "cutoff_angle": math.degrees(half),
            "beam_width": max(math.degrees(beam), 1e-4),
            "to_world": _mat(light.matrix_world @ _FLIP_Z),
        }
        if beam < half:
            tex = _spot_texture(light.spot_size, light.spot_blend)
            if tex is None:
                ctx.approximate(
                    f"light.spot.blend: spot light {light.tag!r} (spot_size {math.degrees(light.spot_size):.1f} deg, "
                    f"spot_blend {light.spot_blend:g}) is too wide or its blend band too narrow for the falloff "
                    "texture: it falls off linearly in angle over the band, Blender's smoothstep in cos(angle)"
                )
            else:
                out["beam_width"] = math.degrees(half)
                out["texture"] = tex
        return out

    @handles(
        AreaLight,
        features={
            "light.area": _exact(
                "rectangle with radiance P / (pi A), one-sided, hidden from the camera (hide_emitters; in scenes "
                "with emissive materials its directly seen emission is subtracted: unbiased, noisy at its outline)"
            ),
            "light.area.disk": _exact("disk with radiance P / (pi A), one-sided, hidden from the camera as light.area"),
        },
    )
    def area_light(self, light: AreaLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """A one-sided ``rectangle`` or ``disk`` (``flip_normals``: it emits along local -Z) with a null BSDF.
        A light lying in the plane of an emissive surface is recorded as an approximation (see
        :func:`_coplanar_emitters`)."""
        if light.strength <= 0:
            return None
        for tag in _coplanar_emitters(light, ctx.scene):
            ctx.approximate(
                f"light.area: area light {light.tag!r} lies in the plane of emissive {tag!r}: Mitsuba's rays meet the "
                "two coincident emitters in arbitrary order (a scene like this measured 1.39x Cycles' light)"
            )
        ctx.null_light_surfaces = max(ctx.null_light_surfaces, 1)
        a, b = light.size
        disk = light.shape in ("circle", "ellipse")
        return {
            "type": "disk" if disk else "rectangle",
            "to_world": _mat(light.matrix_world @ np.diag([a / 2.0, b / 2.0, 1.0, 1.0])),
            "flip_normals": True,
            "bsdf": {"type": "null"},
            "emitter": {"type": "area", "radiance": _rgb(light.radiance)},
        }

    # -- the world --------------------------------------------------------------------------------------
    @handles(BackgroundLight, features={"light.background": _exact("constant emitter")})
    def background_light(self, light: BackgroundLight, ctx: MitsubaContext) -> dict[str, Any] | None:
        """A ``constant`` emitter (unused when an environment map is present: it is added to the map).

        Its light-sampling weight is :data:`BACKGROUND_SAMPLING_WEIGHT` (other emitters: 1): Mitsuba picks
        one emitter per light sample in proportion to these weights, and with equal weights half of a sun's
        samples went to the uniform sky, which BSDF sampling (multiple importance sampling) already finds
        as well as light sampling does; the sun's direct light then came at 0 or 2x its value and its
        noise was 16x Cycles' (benchmarks/results/mitsuba_noise.md). Alone it is still sampled."""
        if light.strength <= 0:
            return None
        return {"type": "constant", "radiance": _rgb(light.radiance), "sampling_weight": BACKGROUND_SAMPLING_WEIGHT}

    @handles(
        EnvironmentMap, features={"light.environment": _exact("envmap rotated to Blender's equirectangular mapping")}
    )
    def environment_map(self, env: EnvironmentMap, ctx: MitsubaContext) -> dict[str, Any] | None:
        """An ``envmap`` reproducing :func:`blendify_core.ir.lights.equirect_uv`, with the background
        light's radiance added.

        Mitsuba's envmap looks up the local direction d at u = atan2(d_x, -d_z) / (2 pi) (mod 1),
        v = acos(d_y) / pi (v = 0 at the top row). Blender's mapping of a world direction w is
        u = 0.5 - atan2(w_y, w_x) / (2 pi), v_top = acos(w_z) / pi. With local = (w_y, w_z, w_x) both agree
        (atan2(w_y, -w_x) = pi - atan2(w_y, w_x)): to_world maps local x -> world y, y -> z, z -> x (a
        proper rotation), composed with the map's own rotation."""
        if env.strength <= 0:
            return None
        img = env.linear_rgb_image().astype(np.float32) * np.float32(env.strength)
        bg = ctx.scene.lights.background if ctx.scene is not None else None
        if bg is not None and bg.strength > 0:
            img = img + np.asarray(bg.radiance, dtype=np.float32)[None, None, :3]
        local_to_world = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        m = np.eye(4)
        m[:3, :3] = env.rotation_matrix @ local_to_world
        return {
            "type": "envmap",
            "bitmap": _mi().Bitmap(blender_rows_for_mitsuba(img)),
            "to_world": _mat(m),
        }

    # -- files of other engines -------------------------------------------------------------------------
    @handles(Attachment)
    def attachment(self, attachment: Attachment, ctx: MitsubaContext) -> None:
        """Attached engine files (.blend) are the Cycles backend's: Mitsuba renders the IR only."""
        ctx.ignore(attachment, f"attached .{attachment.format} files are read by the Cycles backend only")
