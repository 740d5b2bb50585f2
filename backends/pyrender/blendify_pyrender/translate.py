"""IR -> pyrender scene graph: one handler per IR type, its capabilities declared beside it (no rendering here).

:class:`PyrenderTranslator` has a handler for every type of :data:`blendify_core.ir.types.IR_TYPES`;
a type without one (a user's subclass, say) is refused by the base with UnsupportedFeatureError naming the
type and "pyrender". Handlers return plain records the session puts into its cached ``pyrender.Scene``:
renderables a :class:`Built` (pyrender mesh re-centred in object space), lights a :class:`LightBuild`,
the background and environment their ambient radiance, cameras a :class:`CameraBuild`, colour sources a
:class:`Surface` and materials a :class:`PBR` (glTF metallic-roughness parameters, combined with the
colour input by :meth:`PyrenderTranslator.pyrender_material`).

Importing this module imports neither pyrender nor OpenGL (the backend reads its capabilities from here
before any OpenGL platform is chosen): pyrender is imported when a handler first runs, after the session
prepared the platform. Every formula is from ``shared/docs/CONVENTIONS.md`` (sections 1, 5, 6, 7, 8) or
measured where noted; light units and the normal-map strength come from :mod:`blendify_core.ir.physics`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import FacesUV, FileTextureColors, TextureColors, UniformColors, VertexColors, VertexUV
from blendify_core.ir.colorspace import linear_to_srgb8
from blendify_core.ir.geometry import TriMesh, face_normals
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
from blendify_core.ir.physics import area_radiance, blend_normal_map, point_intensity, spot_cone
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
from blendify_core.pipeline.translator import TranslationContext, Translator, approximate, exact, handles

__all__ = [
    "PyrenderTranslator",
    "Built",
    "LightBuild",
    "CameraBuild",
    "Surface",
    "PBR",
    "sphere_quads",
    "environment_mean",
    "emitter_lights",
    "environment_light",
    "environment_sun",
    "environment_background",
    "environment_radiance",
    "EnvironmentLight",
    "uniform_sh",
    "sh_basis",
    "DIFFUSE_COMPENSATION",
    "AREA_INNER_CONE",
    "AREA_OUTER_CONE",
]

#: pyrender's diffuse term is (1 - F) * base * (1 - 0.04) / pi: divide dielectric base colours by this
DIFFUSE_COMPENSATION = 0.96
#: area lights become spot lights with these cones (outer < 84.4 deg keeps the spot shadow camera finite)
#: suns narrower than this keep hard shadows (their penumbra is under ~2 shadow-map texels for blockers within a
#: quarter of the scene's size; Blender's default sun, 0.526 degrees, among them): the soft-shadow variant of the
#: shader costs llvmpipe about 30 % of the colour pass
SUN_SOFT_MIN = float(np.deg2rad(1.0))
AREA_INNER_CONE = np.deg2rad(25.0)
AREA_OUTER_CONE = np.deg2rad(80.0)


def _pyrender() -> Any:
    """pyrender, imported on first use: the session prepared the OpenGL platform before translating."""
    import pyrender

    return pyrender


# ---------------------------------------------------------------------------------------------------
# what the handlers return
# ---------------------------------------------------------------------------------------------------


@dataclass
class Built:
    """A translated renderable: its pyrender mesh (None when it has no faces), the object-space offset
    folded into the node pose (re-centring before float32) and whether it is a shadow catcher."""

    mesh: Any
    offset: np.ndarray
    catcher: bool = False


@dataclass
class LightBuild:
    """A translated light: the pyrender light, its pose and whether it casts shadows."""

    light: Any
    pose: np.ndarray
    casts: bool


@dataclass
class CameraBuild:
    """A translated camera: the OpenGL projection (any principal point, fx != fy, orthographic with an
    offset principal point), clip distances, pose and resolution, and ``screen_size(size, at)``: the size
    in pixels of ``size`` world units at the world point ``at`` (for the per-frame thinning of dense point clouds)."""

    projection: np.ndarray
    znear: float
    zfar: float
    pose: np.ndarray
    width: int
    height: int
    screen_size: Callable[[float, np.ndarray], float]


@dataclass
class Surface:
    """The colour input of one material slot: a uniform linear RGBA, per-vertex linear RGBA, or a
    texture (uploaded as sRGB bytes, decoded by the shader)."""

    rgba: np.ndarray
    vertex_rgba: np.ndarray | None = None
    texture: Any = None
    translucent: bool = False


@dataclass
class PBR:
    """A material as glTF metallic-roughness parameters (before the colour input is applied).
    ``emission`` is the square root of the emitted radiance (pyrender's mesh.frag squares it); ``wire``
    is (thickness in world units, linear RGBA) for wireframe materials."""

    alpha: float
    metallic: float
    roughness: float
    transmission: float = 0.0
    ior: float = 1.5
    roughness_map: Any = None
    metallic_map: Any = None
    normal_map: Any = None
    emission: np.ndarray | None = None
    wire: tuple[float, np.ndarray] | None = None

    @property
    def has_maps(self) -> bool:
        return self.roughness_map is not None or self.metallic_map is not None or self.normal_map is not None


# ---------------------------------------------------------------------------------------------------
# helpers (numpy, and pyrender objects)
# ---------------------------------------------------------------------------------------------------


def _sampler(interpolation: str) -> Any:
    from OpenGL.GL import GL_LINEAR, GL_LINEAR_MIPMAP_LINEAR, GL_NEAREST, GL_REPEAT

    pyrender = _pyrender()
    if interpolation == "closest":
        return pyrender.Sampler(magFilter=GL_NEAREST, minFilter=GL_NEAREST, wrapS=GL_REPEAT, wrapT=GL_REPEAT)
    return pyrender.Sampler(magFilter=GL_LINEAR, minFilter=GL_LINEAR_MIPMAP_LINEAR, wrapS=GL_REPEAT, wrapT=GL_REPEAT)


def _texture_rgba8(colors: TextureColors | FileTextureColors) -> np.ndarray:
    """(H, W, 4) uint8 sRGB-encoded texture (row 0 = top): 8-bit sRGB data as stored, anything else encoded."""
    img = colors.image()
    if img.dtype == np.uint8 and colors.color_space == "srgb":
        if img.shape[2] == 4:
            return np.ascontiguousarray(img)
        rgb = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img
        return np.ascontiguousarray(np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2))
    lin = colors.linear_rgba_image()
    out = np.empty(lin.shape, dtype=np.uint8)
    out[..., :3] = linear_to_srgb8(lin[..., :3])
    out[..., 3] = np.round(np.clip(lin[..., 3], 0, 1) * 255).astype(np.uint8)
    return out


def _map_values(tmap: Any) -> np.ndarray:
    return np.asarray(tmap.values(), dtype=np.float32)


def _resize_nearest(img: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    if img.shape[:2] == shape:
        return img
    rows = np.minimum((np.arange(shape[0]) + 0.5) * img.shape[0] / shape[0], img.shape[0] - 1).astype(int)
    cols = np.minimum((np.arange(shape[1]) + 0.5) * img.shape[1] / shape[1], img.shape[1] - 1).astype(int)
    return img[rows][:, cols]


def _primitive(
    positions: np.ndarray,
    normals: np.ndarray,
    indices: np.ndarray,
    material: Any,
    albedo: np.ndarray,
    uv: np.ndarray | None = None,
    color_0: np.ndarray | None = None,
) -> Any:
    pyrender = _pyrender()
    prim = pyrender.Primitive(
        positions=positions.astype(np.float32, copy=False),
        normals=normals.astype(np.float32, copy=False),
        texcoord_0=None if uv is None else uv.astype(np.float32, copy=False),
        color_0=None if color_0 is None else color_0.astype(np.float32, copy=False),
        indices=indices.astype(np.uint32, copy=False),
        material=material,
        mode=pyrender.constants.GLTF.TRIANGLES,
    )
    # pyrender's ``indices`` setter stores float32, exact only below 2^24 vertices: keep the uint32 indices
    prim._indices = np.ascontiguousarray(indices, dtype=np.uint32)
    prim.albedo_factor = albedo  # read by the G-buffer pass
    return prim


def _wire_tubes(vertices: np.ndarray, faces: np.ndarray, thickness: float) -> tuple[np.ndarray, ...] | None:
    """The triangle edges as square tubes of side ``thickness`` (world units): positions, normals, indices."""
    if thickness <= 0 or len(faces) == 0:
        return None
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    a, b = vertices[e[:, 0]], vertices[e[:, 1]]
    d = b - a
    length = np.linalg.norm(d, axis=1, keepdims=True)
    keep = length[:, 0] > 0
    a, b, d, length = a[keep], b[keep], d[keep], length[keep]
    d = d / length
    helper = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(d, u)
    r = thickness / 2.0
    corners = np.stack([u + w, -u + w, -u - w, u - w], axis=1) / np.sqrt(2.0)  # (E, 4, 3) unit radial
    pos = np.concatenate([a[:, None] + r * np.sqrt(2.0) * corners, b[:, None] + r * np.sqrt(2.0) * corners], axis=1)
    nrm = np.concatenate([corners, corners], axis=1)
    ne = len(a)
    j = np.arange(4)
    jn = (j + 1) % 4
    quad = np.stack([np.stack([j, jn, jn + 4], 1), np.stack([j, jn + 4, j + 4], 1)], axis=1).reshape(-1, 3)
    idx = (quad[None] + (np.arange(ne) * 8)[:, None, None]).reshape(-1, 3)
    return pos.reshape(-1, 3), nrm.reshape(-1, 3), idx


# ---------------------------------------------------------------------------------------------------
# point clouds: exact spheres
# ---------------------------------------------------------------------------------------------------


#: two triangles per point: corners 0-1-2 and 0-2-3 of the quad the shaders spread over the projected sphere
_QUAD = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def sphere_quads(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The corner numbers (4 per point: 0, 1, 2, 3) and the triangle indices (2 per point, (2n, 3)) of n
    point quads (shaders/blendify_sphere_vert.glsl places the corners)."""
    corners = np.tile(np.arange(4, dtype=np.float32), n)
    tris = (_QUAD[None] + (np.arange(n, dtype=np.uint32) * 4)[:, None, None]).reshape(-1, 3)
    return corners, tris


def environment_mean(env: EnvironmentMap) -> np.ndarray:
    """Solid-angle weighted mean radiance (linear RGB) of an equirectangular map, times its strength."""
    img = env.linear_rgb_image().astype(np.float64)
    h = img.shape[0]
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    w = np.cos(lat)[:, None, None]
    mean = (img * w).sum(axis=(0, 1)) / (w.sum() * img.shape[1])
    return mean * float(env.strength)


#: real spherical-harmonic basis up to band 2 and the cosine lobe's band factors A_l / pi (Ramamoorthi and
#: Hanrahan 2001): irradiance / pi at n = sum_k (A_l / pi) L_k Y_k(n)
_SH_BAND_FACTOR = np.array([1.0, 2 / 3, 2 / 3, 2 / 3, 0.25, 0.25, 0.25, 0.25, 0.25])


def sh_basis(d: np.ndarray) -> np.ndarray:
    """(N, 9) real SH basis of unit directions (N, 3), the order of shaders/blendify_env.glsl."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack(
        [
            np.full_like(x, 0.282095),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3 * z * z - 1),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        axis=1,
    )


def uniform_sh(radiance: np.ndarray) -> np.ndarray:
    """(9, 3) coefficients (A_l / pi) L_lm of a uniform radiance (linear RGB) from every direction."""
    out = np.zeros((9, 3))
    out[0] = np.asarray(radiance, dtype=np.float64) * 4.0 * np.pi * 0.282095
    return out


#: a map's "sun": the pixels above this fraction of its peak luminance, when they hold at least
#: SUN_MIN_SHARE of the map's power within SUN_MAX_SOLID_ANGLE steradians
SUN_PEAK_FRACTION = 0.1
SUN_MIN_SHARE = 0.2
SUN_MAX_SOLID_ANGLE = 0.1


@dataclass
class EnvironmentLight:
    """An environment map as the preview shades it: 9 SH coefficients (A_l / pi) L_lm of the map without its
    sun (linear RGB) and the sun as a directional light (``sun_irradiance`` RGB W/m^2 toward
    ``sun_direction``, world, pointing at the sun; None when the map has no dominant peak)."""

    sh: np.ndarray
    sun_direction: np.ndarray | None = None
    sun_irradiance: np.ndarray | None = None
    #: the sun pixels' solid angle (sr): its angular size (soft shadows)
    sun_solid_angle: float = 0.0
    #: luminance (times the strength) above which a pixel belongs to the sun (inf: no sun)
    sun_luminance: float = float("inf")


def environment_light(env: EnvironmentMap, max_rows: int = 64) -> EnvironmentLight:
    """The map (times its strength, rotated) as SH coefficients plus its sun (see :class:`EnvironmentLight`),
    from a copy at most ``max_rows`` rows high (box-averaged)."""
    from blendify_core.ir.transforms import quaternion_to_matrix

    img = env.linear_rgb_image().astype(np.float64) * float(env.strength)
    k = max(1, int(np.ceil(img.shape[0] / max_rows)))
    h, w = img.shape[0] // k, img.shape[1] // k
    img = img[: h * k, : w * k].reshape(h, k, w, k, 3).mean(axis=(1, 3)).reshape(-1, 3)
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)  # row 0 = top (v = 1)
    lon = 2.0 * np.pi * (0.5 - (np.arange(w) + 0.5) / w)  # u = 0.5 - atan2(y, x) / (2 pi)
    lat, lon = np.meshgrid(lat, lon, indexing="ij")
    d = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1).reshape(-1, 3)
    d = d @ quaternion_to_matrix(env.quaternion).T
    d_omega = (2.0 * np.pi / w) * (np.pi / h) * np.cos(lat).reshape(-1)
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    out = EnvironmentLight(np.zeros((9, 3)))
    power = lum * d_omega
    if lum.max(initial=0.0) > 0:
        peak = lum > SUN_PEAK_FRACTION * lum.max()
        if d_omega[peak].sum() <= SUN_MAX_SOLID_ANGLE and power[peak].sum() >= SUN_MIN_SHARE * power.sum():
            e = (img[peak] * d_omega[peak, None]).sum(axis=0)  # irradiance facing the sun
            direction = (d[peak] * power[peak, None]).sum(axis=0)
            out.sun_direction = direction / np.linalg.norm(direction)
            out.sun_irradiance = e
            out.sun_solid_angle = float(d_omega[peak].sum())
            out.sun_luminance = float(SUN_PEAK_FRACTION * lum.max())
            img = img.copy()
            img[peak] = 0.0
    out.sh = (sh_basis(d) * d_omega[:, None]).T @ img * _SH_BAND_FACTOR[:, None]
    return out


def environment_background(env: EnvironmentMap, camera: Any, uniform: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 film background: the map seen through each pixel centre of ``camera`` (bilinear
    between texel centres as Cycles' "Linear" environment texture, wrapping around in u; times its strength)
    plus a ``uniform`` radiance (the background light)."""
    _, dirs = camera.pixel_rays()
    bg = environment_radiance(env, dirs, uniform)
    return bg.reshape(camera.height, camera.width, 3).astype(np.float32)


def environment_radiance(
    env: EnvironmentMap, dirs: np.ndarray, uniform: np.ndarray, sun_luminance: float = float("inf")
) -> np.ndarray:
    """(N, 3) radiance of the map (bilinear, times its strength) in world directions ``dirs`` (N, 3), plus a
    ``uniform`` radiance; texels brighter than ``sun_luminance`` (the map's sun, drawn as a light) count as 0."""
    from blendify_core.ir.lights import equirect_uv

    uv = equirect_uv(dirs @ env.rotation_matrix)  # the map's frame: R^-1 d
    img = env.linear_rgb_image().astype(np.float64) * float(env.strength)
    if np.isfinite(sun_luminance):
        img = np.where((img @ np.array([0.2126, 0.7152, 0.0722]) > sun_luminance)[..., None], 0.0, img)
    h, w = img.shape[:2]
    y = np.clip((1.0 - uv[:, 1]) * h - 0.5, 0.0, h - 1.0)
    x = uv[:, 0] * w - 0.5
    y0, x0 = np.floor(y).astype(np.int64), np.floor(x).astype(np.int64)
    fy, fx = (y - y0)[:, None], (x - x0)[:, None]
    y1 = np.minimum(y0 + 1, h - 1)
    x0, x1 = x0 % w, (x0 + 1) % w
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    texel = top * (1.0 - fy) + bottom * fy
    return np.asarray(texel + np.asarray(uniform, dtype=np.float64))


def environment_sun(light: EnvironmentLight) -> SunLight | None:
    """An IR sun light for the map's sun (None without one): irradiance = the sun pixels' integral, angular
    diameter = the disc of their solid angle."""
    if light.sun_direction is None or light.sun_irradiance is None:
        return None
    z = light.sun_direction  # a sun light shines along its local -Z: +Z points at the sun
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    e = np.asarray(light.sun_irradiance, dtype=np.float64)
    strength = min(float(e.max()), _MAX_POWER)
    # the disc of the sun pixels' solid angle: omega = 2 pi (1 - cos(diameter / 2))
    diameter = 2.0 * float(np.arccos(np.clip(1.0 - light.sun_solid_angle / (2.0 * np.pi), -1.0, 1.0)))
    return SunLight(
        strength=strength,
        angular_diameter=diameter,
        color=tuple(e / float(e.max())),
        color_space="linear",
        rotation_mode="rotmat",
        rotation=np.stack([x, y, z], axis=1),
    )


# ---------------------------------------------------------------------------------------------------
# emissive surfaces as lights
# ---------------------------------------------------------------------------------------------------

#: a face set whose normals all lie within this angle of their mean is treated as planar (one area light)
EMITTER_PLANAR_DEG = 10.0
#: the IR's largest light power (float32 engines): stronger emitters are lit by lights of this power
_MAX_POWER = 1e30


def emitter_lights(r: Any) -> list[Any]:
    """IR lights approximating the light an emissive renderable sends into the scene (empty if it emits
    nothing). Emitted power of a Lambertian emitter of radiance L over an area A: pi x L x A per side; Cycles'
    mesh emission is two-sided. Per emissive material slot: a planar face set becomes two back-to-back
    rectangle area lights of the faces' extent in their plane (each pi L A); any other a point light of power
    2 pi L A at the area centroid (isotropic; exact in the far field of a sphere). Point clouds are left out."""
    if isinstance(r, PointCloud):
        return []
    mats = list(r.materials)
    if not any(getattr(m, "is_emissive", False) for m in mats):
        return []
    tm = r.to_mesh()
    faces = np.asarray(tm.faces, dtype=np.int64)
    if len(faces) == 0:
        return []
    m4 = np.asarray(r.matrix_world, dtype=np.float64)
    v = np.asarray(tm.vertices, dtype=np.float64) @ m4[:3, :3].T + m4[:3, 3]
    fm = getattr(r, "faces_material", None)
    slots = np.zeros(len(faces), dtype=np.int64) if fm is None else np.asarray(fm, dtype=np.int64)
    lights: list[Any] = []
    for k, mat in enumerate(mats):
        if not getattr(mat, "is_emissive", False):
            continue
        f = faces[slots == k]
        if len(f) == 0:
            continue
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        cross = np.cross(b - a, c - a)
        areas = 0.5 * np.linalg.norm(cross, axis=1)
        total = float(areas.sum())
        if total <= 0:
            continue
        centre = (((a + b + c) / 3.0) * areas[:, None]).sum(axis=0) / total
        color = np.clip(mat.linear("emission_color")[:3], 0.0, 1.0)
        power = min(float(np.pi * total * float(mat.emission_strength)), _MAX_POWER / 2.0)  # per side
        n_mean = cross.sum(axis=0)
        n_len = float(np.linalg.norm(n_mean))
        unit = cross / np.maximum(2.0 * areas, 1e-300)[:, None]
        planar = n_len > 0 and bool(
            np.all(unit[areas > 0] @ (n_mean / n_len) >= np.cos(np.deg2rad(EMITTER_PLANAR_DEG)))
        )
        if not planar:
            lights.append(
                PointLight(strength=2.0 * power, color=tuple(color), color_space="linear", translation=tuple(centre))
            )
            continue
        n = n_mean / n_len
        pts = np.concatenate([a, b, c]) - centre
        pts -= np.outer(pts @ n, n)
        _, _, axes = np.linalg.svd(pts, full_matrices=False)
        u = axes[0] - n * float(axes[0] @ n)
        u /= np.linalg.norm(u)
        w = np.cross(n, u)
        size = (float(np.ptp(pts @ u)), float(np.ptp(pts @ w)))
        size = (max(size[0], 1e-6), max(size[1], 1e-6))
        # an equal-area rectangle of the faces' extent ratio (a disk's power spread over its bounding box
        # would be dimmer per area but the same in total: the power is what is kept)
        scale = float(np.sqrt(total / (size[0] * size[1])))
        size = (size[0] * scale, size[1] * scale)
        offset = 1e-4 * max(size)
        for side in (1.0, -1.0):
            # an area light emits along its local -Z: columns (x, y, z) = (u, -side x w, -side x n), a rotation
            rot = np.stack([u, -side * w, -side * n], axis=1)
            lights.append(
                AreaLight(
                    "rectangle",
                    size,
                    strength=power,
                    color=tuple(color),
                    color_space="linear",
                    rotation_mode="rotmat",
                    rotation=rot,
                    translation=tuple(centre + side * offset * n),
                )
            )
    return lights


# ---------------------------------------------------------------------------------------------------
# the translator
# ---------------------------------------------------------------------------------------------------

_SHARED = exact("shared tessellation")


class PyrenderTranslator(Translator):
    """IR -> pyrender: one handler per IR type (see the module docstring for what each returns)."""

    backend = "pyrender"

    #: features not tied to one IR type: implemented by the session and the frame passes (render.py)
    extra_capabilities = {
        "object.no_shadow": exact("the object is left out of the shadow maps"),
        "light.no_shadow": exact("the light's shadow map stays empty"),
        "output.rgb": exact(
            "linear radiance from a float (RGBA32F) colour pass, values above 1 kept (where the driver has no "
            "float render targets: 8-bit, gamma 2.2, clipped at 1, listed in meta['approximations']); "
            "anti-aliased with MSAA (EGL) or supersampling, coverage alpha"
        ),
        "output.depth": exact("planar z from a float G-buffer pass, one sample at the pixel centre"),
        "output.normal": exact("world-space shading normal facing the viewer, G-buffer pass"),
        "output.albedo": exact("linear material colour input x texture x vertex colour, G-buffer pass"),
        "output.instance": exact("exact ids from the G-buffer pass (no anti-aliasing)"),
    }

    # -- renderables ------------------------------------------------------------------------------------
    @handles(
        Mesh,
        features={
            "mesh": exact("rasterised triangles, both faces shaded"),
            "mesh.smooth": exact("interpolated vertex normals"),
            "mesh.faces_material": exact("one pyrender primitive per material slot"),
        },
    )
    def mesh(self, mesh: Mesh, ctx: TranslationContext) -> Built:
        def uvs(tm: TriMesh) -> tuple[np.ndarray | None, np.ndarray | None]:
            uvmap = mesh.uv_map
            if isinstance(uvmap, VertexUV):
                return np.asarray(uvmap.data, dtype=np.float64), None
            if isinstance(uvmap, FacesUV) or tm.uv is not None:
                return None, np.asarray(mesh.triangle_uvs(), dtype=np.float64)
            return None, None

        return self._triangles(mesh, ctx, mesh.faces_material, uvs)

    @handles(CubeMesh, features={"primitive.cube": _SHARED})
    def cube(self, cube: CubeMesh, ctx: TranslationContext) -> Built:
        return self._triangles(cube, ctx, cube.faces_material)

    @handles(CircleMesh, features={"primitive.circle": _SHARED})
    def circle(self, circle: CircleMesh, ctx: TranslationContext) -> Built:
        return self._triangles(circle, ctx, circle.faces_material)

    @handles(CylinderMesh, features={"primitive.cylinder": _SHARED})
    def cylinder(self, cylinder: CylinderMesh, ctx: TranslationContext) -> Built:
        return self._triangles(cylinder, ctx, cylinder.faces_material)

    @handles(
        PlaneMesh,
        features={
            "primitive.plane": _SHARED,
            "shadow_catcher": approximate(
                "two colour passes (with and without the other objects); alpha = 1 - shadowed/unshadowed "
                "radiance of the catcher, shadow-mapped shadows"
            ),
        },
    )
    def plane(self, plane: PlaneMesh, ctx: TranslationContext) -> Built:
        built = self._triangles(plane, ctx, plane.faces_material)
        built.catcher = plane.shadow_catcher  # the frame passes composite it (render.py)
        return built

    @handles(SphereNURBS, features={"primitive.sphere": exact("UV sphere 64x32 (the shared tessellation)")})
    def sphere(self, sphere: SphereNURBS, ctx: TranslationContext) -> Built:
        return self._triangles(sphere, ctx)

    @handles(
        EllipsoidNURBS, features={"primitive.ellipsoid": exact("UV sphere 64x32 scaled (the shared tessellation)")}
    )
    def ellipsoid(self, ellipsoid: EllipsoidNURBS, ctx: TranslationContext) -> Built:
        return self._triangles(ellipsoid, ctx)

    @handles(CurveBezier, features={"primitive.curve": exact("tube tessellation shared with the other backends")})
    def curve(self, curve: CurveBezier, ctx: TranslationContext) -> Built:
        return self._triangles(curve, ctx)

    @handles(
        PointCloud,
        features={
            "pointcloud": exact(
                "exact spheres at pixel centres: one quad per point over the sphere's projected box, the ray "
                "through each pixel centre intersected with the sphere (depth, normal, instance and shadow maps; "
                "perspective and orthographic cameras); the colour of clouds denser than 8 points per covered "
                "pixel comes from a random subset; clouds of spheres under 1.5 px are shaded sphere by sphere as "
                "wholes and splatted by their projected area (coverage anti-aliasing; a random subset of wider "
                "spheres otherwise), listed in result.meta['approximations']"
            ),
            "pointcloud.vertex_colors": approximate("per-point colours multiply the shaded colour (COLOR_0)"),
            "pointcloud.emission": approximate("emission added to the shaded colour; lights nothing else"),
        },
    )
    def pointcloud(self, pc: PointCloud, ctx: TranslationContext) -> Built:
        """Exact spheres: one quad per point (4 vertices at the centre, texcoord_0 = (diameter, corner)) that
        the BLENDIFY_SPHERE shaders spread over the sphere's projected box and intersect per pixel centre."""
        pyrender = _pyrender()
        pts = pc.vertices
        n = len(pts)
        if n == 0:  # nothing to draw (pyrender cannot bound an empty primitive)
            return Built(None, np.zeros(3))
        centre = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        local = (pts - centre).astype(np.float32)
        radii = np.broadcast_to(pc.radii().astype(np.float32), (n,))
        surf = self.dispatch(pc.colors_list[0], ctx)
        pm, albedo = self.pyrender_material(pc.materials[0], surf, False, ctx)
        if pc.particle_emission_strength > 0:
            pm.emissiveFactor = np.sqrt(surf.rgba[:3] * pc.particle_emission_strength)
        # a fixed random order, so that any prefix is a uniform subset (the colour pass draws a prefix when the
        # cloud is so dense on screen that most points would be overdrawn)
        perm = np.random.default_rng(0).permutation(n)
        corners, tris = sphere_quads(n)
        texcoord = np.empty((4 * n, 2), dtype=np.float32)
        texcoord[:, 0] = np.repeat(2.0 * radii[perm], 4)  # the spheres' diameters (object units)
        texcoord[:, 1] = corners
        colors = None if surf.vertex_rgba is None else np.repeat(surf.vertex_rgba[perm].astype(np.float32), 4, axis=0)
        prim = pyrender.Primitive(
            positions=np.repeat(local[perm], 4, axis=0),
            texcoord_0=texcoord,
            color_0=colors,
            indices=tris,
            material=pm,
            mode=pyrender.constants.GLTF.TRIANGLES,
        )
        prim._indices = tris  # not pyrender's float32 copy (inexact above 2^24)
        # drawn after the opaque objects (pyrender's order for transparent ones): the blended edges of the spheres
        # (render.py, the coverage scheme) then lie over what is behind them
        prim._is_transparent = True
        prim.albedo_factor = albedo
        prim.point_diameter = float(np.mean(radii) * 2.0)  # world units (marks the sphere clouds)
        prim.point_diameter_max = float(radii.max(initial=0) * 2.0)
        prim.sphere_scale = 1.0  # diameter factor keeping the coverage of a thinned cloud (set per frame)
        prim.point_all_indices = tris
        prim.point_extent = float(np.max(np.linalg.norm(local, axis=1))) + float(radii.max(initial=0))
        # the spheres' bounds, not the centres' (pyrender frames the sun's shadow camera with them)
        r_max = float(radii.max(initial=0))
        prim._bounds = np.stack([local.min(axis=0) - r_max, local.max(axis=0) + r_max]).astype(np.float64)
        return Built(pyrender.Mesh(primitives=[prim]), centre)

    def _triangles(
        self,
        r: Any,
        ctx: TranslationContext,
        faces_material: np.ndarray | None = None,
        uvs: Callable[[TriMesh], tuple[np.ndarray | None, np.ndarray | None]] | None = None,
    ) -> Built:
        """A renderable's shared tessellation as a pyrender mesh in object space, re-centred: one primitive
        per material slot (and one per wireframe overlay). ``uvs(tm)`` gives (per-vertex UVs, per-corner UVs);
        by default the tessellation's own corner UVs."""
        pyrender = _pyrender()
        tm = r.to_mesh()
        verts = np.asarray(tm.vertices, dtype=np.float64)
        faces = np.asarray(tm.faces, dtype=np.int64)
        if len(faces) == 0:
            return Built(None, np.zeros(3))
        surfaces = [self.dispatch(c, ctx) for c in r.colors_list]
        pbrs = [self.dispatch(m, ctx) for m in r.materials]
        needs_uv = any(s.texture is not None for s in surfaces) or any(p.has_maps for p in pbrs)
        vertex_uv = corner_uv = None
        if needs_uv:
            if uvs is not None:
                vertex_uv, corner_uv = uvs(tm)
            elif tm.uv is not None:
                corner_uv = np.asarray(tm.uv, dtype=np.float64)
        unweld = (not tm.smooth) or tm.normals is None or corner_uv is not None
        if unweld:
            idx = faces.reshape(-1)
            positions = verts[idx]
            if tm.smooth and tm.normals is not None:
                normals = np.asarray(tm.normals)[idx]
            else:
                normals = np.repeat(face_normals(verts, faces), 3, axis=0)
            uv = (
                corner_uv.reshape(-1, 2)
                if corner_uv is not None
                else (vertex_uv[idx] if vertex_uv is not None else None)
            )
            tri = np.arange(3 * len(faces), dtype=np.int64).reshape(-1, 3)
        else:
            idx = None
            positions = verts
            normals = np.asarray(tm.normals)
            uv = vertex_uv
            tri = faces
        centre = (positions.min(axis=0) + positions.max(axis=0)) / 2.0
        positions = positions - centre
        fm = faces_material
        prims = []
        slots = [0] if fm is None else sorted(set(np.unique(fm).tolist()))
        for m in slots:
            sub = tri if fm is None else tri[fm == m]
            if len(sub) == 0:
                continue
            surf, pbr = surfaces[m], pbrs[m]
            color_0 = None
            if surf.vertex_rgba is not None:
                color_0 = surf.vertex_rgba if idx is None else surf.vertex_rgba[idx]
            pm, albedo = self._build_material(pbr, surf, uv is not None, ctx)
            prims.append(_primitive(positions, normals, sub, pm, albedo, uv=uv if needs_uv else None, color_0=color_0))
            if pbr.wire is not None:
                thickness, wire_rgba = pbr.wire
                tubes = _wire_tubes(verts - centre, faces if fm is None else faces[fm == m], thickness)
                if tubes is not None:
                    wire_surf = Surface(rgba=wire_rgba, translucent=bool(wire_rgba[3] < 1))
                    wpm, walbedo = self._build_material(pbr, wire_surf, False, ctx)
                    prims.append(_primitive(*tubes, wpm, walbedo))
        if not prims:
            return Built(None, centre)
        return Built(pyrender.Mesh(primitives=prims), centre)

    # -- colour sources -----------------------------------------------------------------------------------
    @handles(UniformColors)
    def uniform_colors(self, colors: UniformColors, ctx: TranslationContext) -> Surface:
        c = colors.linear_rgba.astype(np.float64)
        return Surface(rgba=c, translucent=bool(c[3] < 1.0))

    @handles(
        VertexColors,
        features={
            "mesh.vertex_colors": approximate(
                "vertex colours multiply the final shaded colour (pyrender COLOR_0), so they also tint highlights"
            )
        },
    )
    def vertex_colors(self, colors: VertexColors, ctx: TranslationContext) -> Surface:
        return Surface(rgba=np.ones(4), vertex_rgba=colors.linear_rgba, translucent=colors.has_alpha)

    @handles(
        TextureColors,
        FileTextureColors,
        features={
            "mesh.texture": exact("sRGB decoded in the shader; float textures are uploaded as 8-bit sRGB"),
            "mesh.file_texture": exact("sRGB decoded in the shader; float images are uploaded as 8-bit sRGB"),
        },
    )
    def texture_colors(self, colors: TextureColors | FileTextureColors, ctx: TranslationContext) -> Surface:
        img = _texture_rgba8(colors)
        tex = _pyrender().Texture(source=img, source_channels="RGBA", sampler=_sampler(colors.interpolation))
        return Surface(rgba=np.ones(4), texture=tex, translucent=bool(np.any(img[..., 3] < 255)))

    # -- materials ----------------------------------------------------------------------------------------
    @handles(
        PrincipledBSDFMaterial,
        DiffuseMaterial,
        MetalMaterial,
        PlasticMaterial,
        features={
            "material.principled": approximate(
                "glTF metallic-roughness BRDF (GGX, F0 = 0.04 fixed: IOR, specular level/tint, anisotropy "
                "ignored), base colour / 0.96 diffuse compensation, direct light only; dielectric speculars "
                "differ ~5-10%"
            ),
            "material.diffuse_only": approximate(
                "pyrender keeps an F0 = 0.04 GGX lobe; base colour / 0.96 gives -0.8% mean vs Lambert (p95 1.5%)"
            ),
            "material.metallic": approximate(
                "GGX metal; reflects the world's light (9 SH coefficients) and, when the indirect-light probe is "
                "rendered from inside the object, what the probe sees (a 32 x 64 equirectangular map, blurred "
                "with roughness): the scene around it from its centre, taken to lie on the scene's bounding "
                "box (parallax: the reflected ray from the surface point, the map looked up towards where it "
                "leaves the box)"
            ),
            "material.transmission": approximate(
                "the transmitted share weight x (1 - F) (Schlick, F0 from the IOR): solid objects are opaque and show,"
                " along the ray refracted in and out as through a sphere, tinted by the base colour once, what the "
                "indirect-light probe rendered from inside them sees (a 32 x 64 map, with parallax from the exit point"
                " on the bounding sphere to the scene's bounding box; they reflect it too) or else the world's light "
                "(the probes'); their shadows let their light through, focused as by a ball lens (a caustic, from the "
                "bounding sphere and the IOR; none for boxy objects); flat ones are see-through with a "
                "Fresnel-weighted opacity, unrefracted, tinted by the base colour (its largest channel through the "
                "blend, the others against the world's radiance behind), their shadows opaque; the diffuse part scaled"
                " by 1 - weight"
            ),
            "material.coat": approximate("coat layer ignored"),
            "material.sheen": approximate("sheen ignored"),
            "material.subsurface": approximate("subsurface ignored (base colour shaded as diffuse)"),
            "material.emission": approximate(
                "emission added to the shaded colour; emissive surfaces light "
                "the scene as lights of the same power (pi x radiance x area per side): a planar emitter as two "
                "back-to-back rectangle area lights, any other as a point light at its area centroid"
            ),
            "material.alpha": approximate("alpha blending, objects sorted by distance; shadows stay opaque"),
            "material.roughness_map": exact("8-bit texture through the mesh UVs"),
            "material.metallic_map": approximate("8-bit texture; the diffuse compensation uses the mean metallic"),
            "material.normal_map": approximate(
                "tangent frame from screen-space derivatives; strength blends toward the flat normal"
            ),
        },
    )
    def principled(self, mat: PrincipledBSDFMaterial, ctx: TranslationContext) -> PBR:
        emission = np.zeros(3)
        if mat.is_emissive:  # pyrender adds emissive_factor * emissive_factor (mesh.frag): pass the square root
            e = mat.linear("emission_color")[:3] * float(mat.emission_strength)
            emission = np.sqrt(np.clip(e, 0.0, None))
        return PBR(
            alpha=float(mat.alpha),
            metallic=float(mat.metallic),
            roughness=float(mat.roughness),
            transmission=float(mat.transmission_weight),
            ior=float(getattr(mat, "ior", 1.5)),
            roughness_map=mat.roughness_map,
            metallic_map=mat.metallic_map,
            normal_map=mat.normal_map,
            emission=emission,
        )

    @handles(
        PrincipledBSDFWireframeMaterial,
        PlasticWireframeMaterial,
        MetalWireframeMaterial,
        features={
            "material.wireframe": approximate(
                "every triangle edge drawn as a square tube of side wireframe_thickness (world units) over the surface"
            )
        },
    )
    def wireframe(self, mat: PrincipledBSDFWireframeMaterial, ctx: TranslationContext) -> PBR:
        pbr = self.principled(mat, ctx)
        pbr.wire = (float(mat.wireframe_thickness), mat.linear("wireframe_color"))
        return pbr

    @handles(
        GlossyBSDFMaterial,
        features={"material.glossy": approximate("metallic GGX with the colour as F0 (distribution ignored)")},
    )
    def glossy(self, mat: GlossyBSDFMaterial, ctx: TranslationContext) -> PBR:
        return PBR(alpha=float(mat.alpha), metallic=1.0, roughness=float(mat.roughness), emission=np.zeros(3))

    def pyrender_material(
        self, mat: Any, surf: Surface, has_uv: bool, ctx: TranslationContext
    ) -> tuple[Any, np.ndarray]:
        """MetallicRoughnessMaterial for an IR material (dispatched to its handler) and a colour input;
        returns it and the albedo factor (linear RGBA, uncompensated) used by the albedo output."""
        return self._build_material(self.dispatch(mat, ctx), surf, has_uv, ctx)

    def _build_material(self, pbr: PBR, surf: Surface, has_uv: bool, ctx: TranslationContext) -> tuple[Any, np.ndarray]:
        pyrender = _pyrender()
        albedo = np.array(surf.rgba, dtype=np.float64)
        alpha = pbr.alpha * float(surf.rgba[3])
        metallic, roughness = pbr.metallic, pbr.roughness
        mr_tex = normal_tex = None
        rmap, mmap, nmap = pbr.roughness_map, pbr.metallic_map, pbr.normal_map
        if pbr.has_maps and not has_uv:
            ctx.approximate("texture maps need UVs (uv_map); ignored on a mesh without them")
            rmap = mmap = nmap = None
        if rmap is not None or mmap is not None:
            r_img = _map_values(rmap) if rmap is not None else None
            m_img = _map_values(mmap) if mmap is not None else None
            shape = (r_img if r_img is not None else m_img).shape[:2]  # type: ignore[union-attr]
            mr = np.ones(shape + (4,), dtype=np.float32)
            if r_img is not None:
                mr[..., 0] = r_img
                roughness = 1.0
            if m_img is not None:
                m_img = _resize_nearest(m_img, shape)
                mr[..., 1] = m_img
                metallic = float(np.mean(m_img))  # for the diffuse compensation only
            mr_u8 = np.round(np.clip(mr, 0, 1) * 255).astype(np.uint8)
            mr_tex = pyrender.Texture(source=mr_u8, source_channels="RGBA", sampler=_sampler("linear"))
            metallic_factor = 1.0 if m_img is not None else metallic
        else:
            metallic_factor = metallic
        if nmap is not None:
            n = blend_normal_map(nmap.normals(), nmap.strength)
            n8 = np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)
            n8 = np.concatenate([n8, np.full(n8.shape[:2] + (1,), 255, np.uint8)], axis=2)
            normal_tex = pyrender.Texture(source=n8, source_channels="RGBA", sampler=_sampler("linear"))
        k = 1.0 - (1.0 - DIFFUSE_COMPENSATION) * (1.0 - min(max(metallic, 0.0), 1.0))
        base = np.empty(4)
        base[:3] = albedo[:3] / k
        base[3] = alpha
        translucent = alpha < 1.0 or surf.translucent or pbr.transmission > 0
        pm = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=base,
            metallicFactor=float(metallic_factor),
            roughnessFactor=float(roughness),
            emissiveFactor=pbr.emission if pbr.emission is not None else np.zeros(3),
            baseColorTexture=surf.texture,
            metallicRoughnessTexture=mr_tex,
            normalTexture=normal_tex,
            alphaMode="BLEND" if translucent else "OPAQUE",
            doubleSided=True,
        )
        if pbr.transmission > 0:  # render.py's glass patch: refracted world (solid) or see-through (flat)
            f0 = ((pbr.ior - 1.0) / (pbr.ior + 1.0)) ** 2
            glass = [min(pbr.transmission, 1.0), f0, max(pbr.ior, 1.0), 0.0]  # [3]: solid, set per primitive
            pm.blendify_glass = np.array(glass, dtype=np.float32)
        albedo_factor = np.array([albedo[0], albedo[1], albedo[2], 1.0])
        return pm, albedo_factor

    # -- lights (CONVENTIONS 5): None for a light of strength 0 -------------------------------------------
    @handles(
        PointLight,
        features={
            "light.point": approximate(
                "intensity P/(4 pi) W/sr exact, but no shadows (pyrender has no point-light shadow maps)"
            ),
            "light.point.soft": approximate(
                "point lights: radius ignored (no shadows); spot lights: soft shadows of that radius from the one "
                "shadow map (percentage-closer soft shadows: penumbra from the mean blocker depth)"
            ),
        },
    )
    def point_light(self, light: PointLight, ctx: TranslationContext) -> LightBuild | None:
        if light.strength <= 0:
            return None
        pl = _pyrender().PointLight(color=_light_color(light), intensity=point_intensity(light.strength))
        return LightBuild(pl, light.matrix_world, casts=False)

    @handles(
        SunLight,
        features={
            "light.sun": exact("irradiance exact; shadows shadow-mapped (2048^2 over the scene bounds, PCF)"),
            "light.sun.soft": approximate(
                "soft shadows of that angular size from the one shadow map (percentage-closer soft shadows: "
                "penumbra from the mean blocker depth); suns under 1 degree keep hard shadows"
            ),
        },
    )
    def sun_light(self, light: SunLight, ctx: TranslationContext) -> LightBuild | None:
        if light.strength <= 0:
            return None
        pl = _pyrender().DirectionalLight(color=_light_color(light), intensity=float(light.strength))
        # soft shadows (render.py) for suns of at least SUN_SOFT_MIN: smaller ones keep pyrender's hard 3x3 PCF
        soft = light.angular_diameter >= SUN_SOFT_MIN
        pl.blendify_soft = float(np.tan(0.5 * light.angular_diameter)) if soft else 0.0
        return LightBuild(pl, light.matrix_world, casts=bool(light.use_shadow))

    @handles(
        SpotLight,
        features={
            "light.spot": exact(
                "intensity P/(4 pi) W/sr, cone half-angle exact; shadow-mapped shadows (none for cones over 160 deg)"
            ),
            "light.spot.blend": exact(
                "Blender's smoothstep over the blend band (pyrender's shader patched; its own edge was quadratic)"
            ),
        },
    )
    def spot_light(self, light: SpotLight, ctx: TranslationContext) -> LightBuild | None:
        if light.strength <= 0:
            return None
        half, inner = spot_cone(light.spot_size, light.spot_blend)
        pl = _pyrender().SpotLight(
            color=_light_color(light),
            intensity=point_intensity(light.strength),
            innerConeAngle=min(inner, half),
            outerConeAngle=half,
        )
        pl.blendify_soft = float(light.shadow_soft_size)  # soft shadows (render.py)
        return LightBuild(pl, light.matrix_world, casts=_spot_casts(light, pl))

    @handles(
        AreaLight,
        features={
            "light.area": approximate(
                "radiance P/(pi A) integrated over the rectangle in the shader (6 x 6 cosine emitters; within 2 % "
                "of Cycles on a lit plane); soft shadows from one shadow map at the centre (80 deg cone; percentage-"
                "closer soft shadows for the equal-area disc)"
            ),
            "light.area.disk": approximate(
                "as light.area over the disk/ellipse (equal-area concentric cells); soft shadows as light.area"
            ),
        },
    )
    def area_light(self, light: AreaLight, ctx: TranslationContext) -> LightBuild | None:
        if light.strength <= 0:
            return None
        # a spot light carries the area light through pyrender (its shadow map, its slot in the shader's
        # light arrays); the patched shader integrates the emitter's radiance over its surface instead of
        # the spot's cone (blendify_pyrender.render, shaders/blendify_area.glsl)
        pl = _pyrender().SpotLight(
            color=_light_color(light),
            intensity=area_radiance(light.strength, light.area),
            innerConeAngle=float(AREA_INNER_CONE),
            outerConeAngle=float(AREA_OUTER_CONE),
        )
        a, b = light.size
        pl.blendify_area = (2.0 if light.shape in ("circle", "ellipse") else 1.0, a / 2.0, b / 2.0)
        pl.blendify_soft = float(np.sqrt(light.area / np.pi))  # soft shadows: the equal-area disc's radius
        return LightBuild(pl, light.matrix_world, casts=_spot_casts(light, pl))

    # -- the world: uniform ambient radiance (linear RGB) ------------------------------------------------
    @handles(
        BackgroundLight,
        features={
            "light.background": approximate(
                "uniform light: diffuse albedo x radiance, glossy and metal surfaces reflect it (split-sum "
                "environment BRDF); with solid objects the diffuse term takes it through light probes (half "
                "their occlusion, plus two bounces of light: blendify_pyrender.probe); not visible "
                "(transparent film)"
            )
        },
    )
    def background(self, bg: BackgroundLight, ctx: TranslationContext) -> np.ndarray:
        return bg.radiance if bg.strength > 0 else np.zeros(3)

    @handles(
        EnvironmentMap,
        features={
            "light.environment": approximate(
                "image-based light from the map's 9 spherical-harmonic coefficients: diffuse "
                "irradiance, and a glossy term (the SH radiance in the mirror direction, blurred toward the "
                "irradiance with roughness; split-sum environment BRDF) and its sun (pixels above 10 % of the "
                "peak) as a directional light with soft shadows of its size; diffuse light through one light "
                "probe as light.background; seen behind the objects on an opaque film (bilinear, as Cycles)"
            )
        },
    )
    def environment(self, env: EnvironmentMap, ctx: TranslationContext) -> np.ndarray:
        return environment_mean(env) if env.strength > 0 else np.zeros(3)

    # -- cameras (OpenCV pixel centres are integers: the continuous principal point is (cx + 0.5, cy + 0.5),
    #    CONVENTIONS 1.2/1.3) ---------------------------------------------------------------------------------
    @handles(
        PerspectiveCamera,
        features={
            "camera.perspective": exact("exact OpenGL projection from K (any principal point)"),
            "camera.anisotropic": exact("fx != fy in the projection matrix"),
        },
    )
    def perspective_camera(self, cam: PerspectiveCamera, ctx: TranslationContext) -> CameraBuild:
        w, h, n, f = cam.width, cam.height, cam.near, cam.far
        p = np.zeros((4, 4))
        p[0, 0] = 2.0 * cam.fx / w
        p[0, 2] = 1.0 - 2.0 * (cam.cx + 0.5) / w
        p[1, 1] = 2.0 * cam.fy / h
        p[1, 2] = 2.0 * (cam.cy + 0.5) / h - 1.0
        p[2, 2] = (f + n) / (n - f)
        p[2, 3] = 2.0 * f * n / (n - f)
        p[3, 2] = -1.0
        fx, origin, viewdir = cam.fx, cam.translation.copy(), cam.viewdir

        def screen_size(size: float, at: np.ndarray) -> float:
            z = max(float(np.dot(at - origin, viewdir)), n)  # planar depth of ``at``
            return size * fx / z

        return CameraBuild(p, n, f, cam.matrix_world, w, h, screen_size)

    @handles(
        OrthographicCamera,
        features={"camera.orthographic": exact("exact orthographic projection with the principal point")},
    )
    def orthographic_camera(self, cam: OrthographicCamera, ctx: TranslationContext) -> CameraBuild:
        w, h, n, f = cam.width, cam.height, cam.near, cam.far
        s = cam.pixel_size
        p = np.zeros((4, 4))
        p[0, 0] = 2.0 / (s * w)
        p[0, 3] = 2.0 * (cam.cx + 0.5) / w - 1.0
        p[1, 1] = 2.0 / (s * h)
        p[1, 3] = 1.0 - 2.0 * (cam.cy + 0.5) / h
        p[2, 2] = -2.0 / (f - n)
        p[2, 3] = -(f + n) / (f - n)
        p[3, 3] = 1.0

        def screen_size(size: float, at: np.ndarray) -> float:
            return size / s

        return CameraBuild(p, n, f, cam.matrix_world, w, h, screen_size)

    # -- attachments ----------------------------------------------------------------------------------------
    @handles(Attachment)
    def attachment(self, attachment: Attachment, ctx: TranslationContext) -> None:
        ctx.ignore(attachment, f"pyrender draws the IR scene only; the attached .{attachment.format} file is not read")


def _light_color(light: Any) -> np.ndarray:
    return np.clip(light.linear_color, 0.0, None)


def _spot_casts(light: Any, pl: Any) -> bool:
    """pyrender's spot shadow camera has a field of view of 2 x cone + 11.25 deg (< 180): wider cones cast none."""
    return bool(light.use_shadow) and not pl.outerConeAngle > AREA_OUTER_CONE + 1e-9
