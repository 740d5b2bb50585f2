"""IR -> pyrender scene graph: cameras, meshes, point clouds, materials, lights (no rendering here).

Import only after the OpenGL platform was prepared (pyrender imports OpenGL). Every formula is from
``shared/docs/CONVENTIONS.md`` (sections 1, 5, 6, 7, 8) or measured where noted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyrender
from OpenGL.GL import GL_LINEAR, GL_LINEAR_MIPMAP_LINEAR, GL_NEAREST, GL_REPEAT

from blendify_core.ir.cameras import Camera, OrthographicCamera
from blendify_core.ir.colors import FacesUV, FileTextureColors, TextureColors, UniformColors, VertexColors, VertexUV
from blendify_core.ir.colorspace import linear_to_srgb8
from blendify_core.ir.geometry import face_normals, icosphere
from blendify_core.ir.lights import AreaLight, EnvironmentMap, PointLight, SpotLight, SunLight
from blendify_core.ir.materials import Material
from blendify_core.ir.renderables import Mesh, MeshPrimitive, PlaneMesh, PointCloud, Renderable

__all__ = [
    "MatrixCamera",
    "projection_matrix",
    "build_renderable",
    "build_lights",
    "ambient_radiance",
    "PointLOD",
    "point_lod",
    "DIFFUSE_COMPENSATION",
    "AREA_INNER_CONE",
    "AREA_OUTER_CONE",
]

#: pyrender's diffuse term is (1 - F) * base * (1 - 0.04) / pi: divide dielectric base colours by this
DIFFUSE_COMPENSATION = 0.96
#: area lights become spot lights with these cones (outer < 84.4 deg keeps the spot shadow camera finite)
AREA_INNER_CONE = np.deg2rad(25.0)
AREA_OUTER_CONE = np.deg2rad(80.0)


# ---------------------------------------------------------------------------------------------------
# camera
# ---------------------------------------------------------------------------------------------------


class MatrixCamera(pyrender.Camera):
    """A pyrender camera with an explicit OpenGL projection matrix (any principal point, fx != fy,
    orthographic with an offset principal point). The matrix does not depend on the viewport size as
    long as the viewport is the camera resolution times an integer (supersampling)."""

    def __init__(self, projection: np.ndarray, znear: float, zfar: float) -> None:
        super().__init__(znear=znear, zfar=zfar)
        self.projection = np.asarray(projection, dtype=np.float64)

    def get_projection_matrix(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        return self.projection


def projection_matrix(cam: Camera) -> np.ndarray:
    """OpenGL projection of an IR camera. OpenCV pixel centres are integers, so the continuous principal
    point is (cx + 0.5, cy + 0.5) (CONVENTIONS 1.2/1.3)."""
    w, h = cam.width, cam.height
    n, f = cam.near, cam.far
    cxp, cyp = cam.cx + 0.5, cam.cy + 0.5
    p = np.zeros((4, 4))
    if isinstance(cam, OrthographicCamera):
        s = cam.pixel_size
        p[0, 0] = 2.0 / (s * w)
        p[0, 3] = 2.0 * cxp / w - 1.0
        p[1, 1] = 2.0 / (s * h)
        p[1, 3] = 1.0 - 2.0 * cyp / h
        p[2, 2] = -2.0 / (f - n)
        p[2, 3] = -(f + n) / (f - n)
        p[3, 3] = 1.0
    else:
        p[0, 0] = 2.0 * cam.fx / w
        p[0, 2] = 1.0 - 2.0 * cxp / w
        p[1, 1] = 2.0 * cam.fy / h
        p[1, 2] = 2.0 * cyp / h - 1.0
        p[2, 2] = (f + n) / (n - f)
        p[2, 3] = 2.0 * f * n / (n - f)
        p[3, 2] = -1.0
    return p


# ---------------------------------------------------------------------------------------------------
# colours and materials
# ---------------------------------------------------------------------------------------------------


@dataclass
class Surface:
    """The colour input of one material slot: a uniform linear RGBA, per-vertex linear RGBA, or a
    texture (uploaded as sRGB bytes, decoded by the shader)."""

    rgba: np.ndarray
    vertex_rgba: np.ndarray | None = None
    texture: Any = None
    translucent: bool = False


def _sampler(interpolation: str) -> Any:
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


def surface_of(colors: Any) -> Surface:
    if isinstance(colors, UniformColors):
        c = colors.linear_rgba.astype(np.float64)
        return Surface(rgba=c, translucent=bool(c[3] < 1.0))
    if isinstance(colors, VertexColors):
        v = colors.linear_rgba
        return Surface(rgba=np.ones(4), vertex_rgba=v, translucent=colors.has_alpha)
    if isinstance(colors, (TextureColors, FileTextureColors)):
        img = _texture_rgba8(colors)
        tex = pyrender.Texture(source=img, source_channels="RGBA", sampler=_sampler(colors.interpolation))
        return Surface(rgba=np.ones(4), texture=tex, translucent=bool(np.any(img[..., 3] < 255)))
    raise TypeError(f"unknown colour source {type(colors).__name__}")


def _emission(mat: Material) -> np.ndarray:
    """pyrender adds ``emissive_factor * emissive_factor`` (mesh.frag), so pass the square root."""
    if not mat.is_emissive:
        return np.zeros(3)
    e = mat.linear("emission_color")[:3] * float(mat.get("emission_strength"))
    return np.sqrt(np.clip(e, 0.0, None))


def _map_values(tmap: Any) -> np.ndarray:
    return np.asarray(tmap.values(), dtype=np.float32)


def _resize_nearest(img: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    if img.shape[:2] == shape:
        return img
    rows = np.minimum((np.arange(shape[0]) + 0.5) * img.shape[0] / shape[0], img.shape[0] - 1).astype(int)
    cols = np.minimum((np.arange(shape[1]) + 0.5) * img.shape[1] / shape[1], img.shape[1] - 1).astype(int)
    return img[rows][:, cols]


def pbr_material(mat: Material, surf: Surface, has_uv: bool, notes: list[str]) -> tuple[Any, np.ndarray]:
    """MetallicRoughnessMaterial for an IR material and colour input; returns it and the albedo factor
    (linear RGBA, uncompensated) used by the albedo output."""
    v = mat.parameters()
    albedo = np.array(surf.rgba, dtype=np.float64)
    alpha = float(v.get("alpha", 1.0)) * float(surf.rgba[3])
    if mat.kind == "glossy":
        metallic, roughness = 1.0, float(v["roughness"])
    else:
        metallic, roughness = float(v.get("metallic", 0.0)), float(v.get("roughness", 0.5))
        tw = float(v.get("transmission_weight", 0.0))
        if tw > 0:  # no refraction: a see-through hint
            alpha *= 1.0 - 0.7 * tw
    mr_tex = normal_tex = None
    rmap, mmap, nmap = v.get("roughness_map"), v.get("metallic_map"), v.get("normal_map")
    if (rmap is not None or mmap is not None or nmap is not None) and not has_uv:
        notes.append("texture maps need UVs (uv_map); ignored on a mesh without them")
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
        n = nmap.normals()
        s = float(nmap.strength)
        n = np.array([0.0, 0.0, 1.0]) + s * (n - np.array([0.0, 0.0, 1.0]))
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        n8 = np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)
        n8 = np.concatenate([n8, np.full(n8.shape[:2] + (1,), 255, np.uint8)], axis=2)
        normal_tex = pyrender.Texture(source=n8, source_channels="RGBA", sampler=_sampler("linear"))
    k = 1.0 - (1.0 - DIFFUSE_COMPENSATION) * (1.0 - min(max(metallic, 0.0), 1.0))
    base = np.empty(4)
    base[:3] = albedo[:3] / k
    base[3] = alpha
    translucent = alpha < 1.0 or surf.translucent
    pm = pyrender.MetallicRoughnessMaterial(
        baseColorFactor=base,
        metallicFactor=float(metallic_factor),
        roughnessFactor=float(roughness),
        emissiveFactor=_emission(mat),
        baseColorTexture=surf.texture,
        metallicRoughnessTexture=mr_tex,
        normalTexture=normal_tex,
        alphaMode="BLEND" if translucent else "OPAQUE",
        doubleSided=True,
    )
    albedo_factor = np.array([albedo[0], albedo[1], albedo[2], 1.0])
    return pm, albedo_factor


def _primitive(
    positions: np.ndarray,
    normals: np.ndarray,
    indices: np.ndarray,
    material: Any,
    albedo: np.ndarray,
    uv: np.ndarray | None = None,
    color_0: np.ndarray | None = None,
) -> Any:
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


# ---------------------------------------------------------------------------------------------------
# renderables
# ---------------------------------------------------------------------------------------------------


@dataclass
class Built:
    """A translated renderable: its pyrender mesh (None when it has no faces), the object-space offset
    folded into the node pose (re-centring before float32), and notes for result.meta."""

    mesh: Any
    offset: np.ndarray
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class PointLOD:
    """Point-cloud tessellation: the sphere mesh per point and whether it is a level-of-detail fallback."""

    name: str
    subdivisions: int  # icosphere subdivisions, -1 = octahedron, -2 = screen-space squares (GL points)
    reduced: bool


#: thresholds chosen by measurement (benchmarks/bench_pyrender_points.py)
_LODS = (
    (20_000, PointLOD("icosphere-1 (80 triangles per point)", 1, False)),
    (50_000, PointLOD("icosphere-0 (20 triangles per point)", 0, True)),
    (100_000, PointLOD("octahedron (8 triangles per point)", -1, True)),
)
_LOD_LARGE = PointLOD(
    "screen-space squares of the projected diameter at the cloud's median depth (GL points, shaded facing the camera)",
    -2,
    True,
)


def point_lod(n_points: int) -> PointLOD:
    """The tessellation used for a cloud of ``n_points`` points."""
    for limit, lod in _LODS:
        if n_points <= limit:
            return lod
    return _LOD_LARGE


def _unit_sphere(lod: PointLOD) -> tuple[np.ndarray, np.ndarray]:
    if lod.subdivisions < 0:
        v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
        f = np.array(
            [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], dtype=np.int64
        )
        return v, f
    s = icosphere(lod.subdivisions)
    return s.vertices, s.faces.astype(np.int64)


def _pointcloud(pc: PointCloud, mat: Material, notes: list[str]) -> tuple[Any, np.ndarray]:
    pts = pc.vertices
    n = len(pts)
    lod = point_lod(n)
    if lod.reduced:
        notes.append(f"pointcloud LOD: {n} points drawn as {lod.name} instead of icosphere-1 spheres")
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2.0 if n else np.zeros(3)
    local = (pts - centre).astype(np.float32)
    radii = pc.radii().astype(np.float32)
    surf = surface_of(pc.colors_list[0])
    if lod.subdivisions == -2:
        # GL points, in a fixed random order so that any prefix is a uniform subset (drawn per frame when the
        # cloud is so dense on screen that most points would be overdrawn)
        perm = np.random.default_rng(0).permutation(n)
        pm, albedo = pbr_material(mat, surf, False, notes)
        if pc.particle_emission_strength > 0:
            pm.emissiveFactor = np.sqrt(surf.rgba[:3] * pc.particle_emission_strength)
        prim = pyrender.Primitive(
            positions=local[perm],
            color_0=None if surf.vertex_rgba is None else surf.vertex_rgba[perm].astype(np.float32),
            indices=np.arange(n, dtype=np.uint32),
            material=pm,
            mode=pyrender.constants.GLTF.POINTS,
        )
        prim._indices = np.arange(n, dtype=np.uint32)  # not pyrender's float32 copy (inexact above 2^24)
        prim.albedo_factor = albedo
        prim.point_diameter = float(np.mean(radii) * 2.0)  # world units; pixels are set per frame
        prim.point_all_indices = prim._indices
        prim.point_extent = float(np.max(np.linalg.norm(local, axis=1)) if n else 0.0) + float(radii.max(initial=0))
        return pyrender.Mesh(primitives=[prim]), centre
    unit, tris = _unit_sphere(lod)
    nv = len(unit)
    unit32 = unit.astype(np.float32)
    positions = (unit32[None] * radii[:, None, None] + local[:, None, :]).reshape(-1, 3)
    normals = np.broadcast_to(unit32, (n, nv, 3)).reshape(-1, 3)
    indices = (tris[None].astype(np.uint32) + (np.arange(n, dtype=np.uint32) * nv)[:, None, None]).reshape(-1, 3)
    color_0 = None
    if surf.vertex_rgba is not None:
        color_0 = np.repeat(surf.vertex_rgba, nv, axis=0)
    pm, albedo = pbr_material(mat, surf, False, notes)
    if pc.particle_emission_strength > 0:
        pm.emissiveFactor = np.sqrt(surf.rgba[:3] * pc.particle_emission_strength)
    prim = _primitive(positions, normals, indices, pm, albedo, color_0=color_0)
    return pyrender.Mesh(primitives=[prim]), centre


def _wireframe(
    vertices: np.ndarray, faces: np.ndarray, mat: Material, notes: list[str]
) -> tuple[Any, np.ndarray] | None:
    """The triangle edges as square tubes of side ``wireframe_thickness`` (world units) in the wire colour."""
    thickness = float(mat.get("wireframe_thickness"))
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
    wire_rgba = mat.linear("wireframe_color")
    surf = Surface(rgba=wire_rgba, translucent=bool(wire_rgba[3] < 1))
    pm, albedo = pbr_material(mat, surf, False, notes)
    return _primitive(pos.reshape(-1, 3), nrm.reshape(-1, 3), idx, pm, albedo), np.zeros(3)


def build_renderable(r: Renderable) -> Built:
    """Translate one renderable to a pyrender mesh (object space, re-centred)."""
    notes: list[str] = []
    if isinstance(r, PointCloud):
        if r.num_vertices == 0:  # nothing to draw (pyrender cannot bound an empty primitive)
            return Built(None, np.zeros(3), notes)
        mesh, centre = _pointcloud(r, r.materials[0], notes)
        return Built(mesh, centre, notes)
    tm = r.to_mesh()
    verts = np.asarray(tm.vertices, dtype=np.float64)
    faces = np.asarray(tm.faces, dtype=np.int64)
    if len(faces) == 0:
        return Built(None, np.zeros(3), notes)
    surfaces = [surface_of(c) for c in r.colors_list]
    needs_uv = any(s.texture is not None for s in surfaces) or any(
        m.parameters().get(k) is not None for m in r.materials for k in ("roughness_map", "metallic_map", "normal_map")
    )
    vertex_uv = None
    corner_uv = None
    if needs_uv:
        uvmap = r.uv_map if isinstance(r, Mesh) else None
        if isinstance(uvmap, VertexUV):
            vertex_uv = np.asarray(uvmap.data, dtype=np.float64)
        elif isinstance(uvmap, FacesUV) or tm.uv is not None:
            corner_uv = np.asarray(r.triangle_uvs() if isinstance(r, Mesh) else tm.uv, dtype=np.float64)
    unweld = (not tm.smooth) or tm.normals is None or corner_uv is not None
    if unweld:
        idx = faces.reshape(-1)
        positions = verts[idx]
        if tm.smooth and tm.normals is not None:
            normals = np.asarray(tm.normals)[idx]
        else:
            normals = np.repeat(face_normals(verts, faces), 3, axis=0)
        uv = corner_uv.reshape(-1, 2) if corner_uv is not None else (vertex_uv[idx] if vertex_uv is not None else None)
        tri = np.arange(3 * len(faces), dtype=np.int64).reshape(-1, 3)
    else:
        idx = None
        positions = verts
        normals = np.asarray(tm.normals)
        uv = vertex_uv
        tri = faces
    centre = (positions.min(axis=0) + positions.max(axis=0)) / 2.0
    positions = positions - centre
    fm = r.faces_material if isinstance(r, (Mesh, MeshPrimitive)) else None
    prims = []
    slots = [0] if fm is None else sorted(set(np.unique(fm).tolist()))
    for m in slots:
        sub = tri if fm is None else tri[fm == m]
        if len(sub) == 0:
            continue
        surf = surfaces[m]
        mat = r.materials[m]
        color_0 = None
        if surf.vertex_rgba is not None:
            color_0 = surf.vertex_rgba if idx is None else surf.vertex_rgba[idx]
        pm, albedo = pbr_material(mat, surf, uv is not None, notes)
        prims.append(_primitive(positions, normals, sub, pm, albedo, uv=uv if needs_uv else None, color_0=color_0))
        if mat.has_wireframe:
            wire = _wireframe(verts - centre, faces if fm is None else faces[fm == m], mat, notes)
            if wire is not None:
                prims.append(wire[0])
    if not prims:
        return Built(None, centre, notes)
    return Built(pyrender.Mesh(primitives=prims), centre, notes)


def is_shadow_catcher(r: Renderable) -> bool:
    return isinstance(r, PlaneMesh) and r.shadow_catcher


# ---------------------------------------------------------------------------------------------------
# lights
# ---------------------------------------------------------------------------------------------------


def build_lights(lights: Any) -> list[tuple[Any, Any, np.ndarray, bool]]:
    """(IR light, pyrender light, pose, casts shadow) for every light with strength > 0 (CONVENTIONS 5)."""
    out = []
    for light in lights:
        if light.strength <= 0:
            continue
        color = np.clip(light.linear_color, 0.0, None)
        pose = light.matrix_world
        if isinstance(light, SunLight):
            pl = pyrender.DirectionalLight(color=color, intensity=float(light.strength))
        elif isinstance(light, SpotLight):
            half = min(float(light.spot_size) / 2.0, np.pi / 2.0)
            b = float(light.spot_blend)
            inner = float(np.arccos(np.clip(b + (1.0 - b) * np.cos(half), -1.0, 1.0)))
            pl = pyrender.SpotLight(
                color=color,
                intensity=float(light.strength) / (4.0 * np.pi),
                innerConeAngle=min(inner, half),
                outerConeAngle=half,
            )
        elif isinstance(light, AreaLight):
            pl = pyrender.SpotLight(
                color=color,
                intensity=float(light.strength) / np.pi,
                innerConeAngle=float(AREA_INNER_CONE),
                outerConeAngle=float(AREA_OUTER_CONE),
            )
        elif isinstance(light, PointLight):
            pl = pyrender.PointLight(color=color, intensity=float(light.strength) / (4.0 * np.pi))
        else:  # pragma: no cover - the IR has no other light types
            continue
        casts = bool(light.use_shadow) and not isinstance(light, PointLight)
        if isinstance(pl, pyrender.SpotLight) and pl.outerConeAngle > AREA_OUTER_CONE + 1e-9:
            casts = False  # pyrender's spot shadow camera has a field of view of 2 x cone + 11.25 deg (< 180)
        out.append((light, pl, pose, casts))
    return out


def environment_mean(env: EnvironmentMap) -> np.ndarray:
    """Solid-angle weighted mean radiance (linear RGB) of an equirectangular map, times its strength."""
    img = env.linear_rgb_image().astype(np.float64)
    h = img.shape[0]
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    w = np.cos(lat)[:, None, None]
    mean = (img * w).sum(axis=(0, 1)) / (w.sum() * img.shape[1])
    return mean * float(env.strength)


def ambient_radiance(lights: Any) -> np.ndarray:
    """Uniform radiance of the background light plus the mean of the environment map (linear RGB)."""
    total = np.zeros(3)
    bg = lights.background
    if bg is not None and bg.strength > 0:
        total += bg.radiance
    env = lights.environment
    if env is not None and env.strength > 0:
        total += environment_mean(env)
    return total
