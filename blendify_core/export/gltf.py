"""glTF 2.0 export of an IR scene (``scene.export("x.glb")`` / ``scene.export("x.gltf")``), written directly
from the IR with numpy and json (no engine, no extra dependency; PNG textures with Pillow).

What is written (docs/export.md has the table):

- every renderable as a node (its tag as the name, its pose as translation + rotation) with a mesh: meshes,
  the primitives (cube, cylinder, ...) and parametric objects (sphere, ellipsoid, curve tube) tessellated as
  every tessellating backend does (``to_mesh()``); one glTF primitive per material slot; smooth shading as
  ``NORMAL``, flat shading as no normals (glTF viewers then shade flat); UVs as ``TEXCOORD_n`` (v flipped:
  glTF's UV origin is the top-left); vertex colours as linear float ``COLOR_0``;
- point clouds as ``POINTS`` primitives (``points="points"``, the default; the point size, which glTF cannot
  express, is kept in the primitive's ``extras.point_size``, per-point sizes in a ``_POINT_SIZE`` attribute)
  or as merged icospheres (``points="spheres"``);
- materials as metallic-roughness PBR: base colour (linear factor, or an sRGB PNG texture), metallic,
  roughness (with ``roughness_map`` / ``metallic_map`` packed into one metallicRoughness texture), normal
  map, emission, alpha; transmission, IOR, clear coat, sheen and the specular level through the
  ``KHR_materials_*`` extensions;
- the camera (perspective: ``yfov`` and the aspect ratio; orthographic: ``xmag``/``ymag``);
- point, spot and sun lights as ``KHR_lights_punctual``: intensities are photometric there, so watts are
  converted with ``lumens_per_watt`` (683 lm/W, the luminous efficacy at 555 nm): a point or spot light of
  P watts gets ``P / (4 pi) * 683`` candela, a sun of E W/m^2 ``E * 683`` lux; an area light (not
  representable) becomes a spot light of half-angle 90 degrees with the emitter's on-axis intensity
  ``P / pi * 683`` candela. Each light node keeps the IR values (watts, W/m^2) in its ``extras``.

glTF is +Y up and the IR (Blender) +Z up: the scene hangs under one root node rotated -90 degrees about X
(``y_up=True``, what Blender's glTF importer undoes); ``y_up=False`` writes the IR's axes unchanged.
What glTF cannot express (wireframes, shadow catchers, the world light, anisotropy, subsurface, thin film,
an off-centre principal point, ...) is listed in ``asset.extras["blendify_approximations"]`` and in one
warning.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError, UnsupportedFeatureError
from blendify_core.io.output import atomic_write
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import (
    FileTextureColors,
    NormalMap,
    TextureColors,
    TextureMap,
    UniformColors,
    UVMap,
    VertexColors,
    VertexUV,
)
from blendify_core.ir.colorspace import linear_to_srgb8
from blendify_core.ir.from_trimesh import GLTF_ROOT
from blendify_core.ir.lights import AreaLight, PointLight, SpotLight, SunLight
from blendify_core.ir.materials import GlossyBSDFMaterial
from blendify_core.ir.physics import point_intensity, spot_cone
from blendify_core.ir.renderables import Mesh, PlaneMesh, PointCloud
from blendify_core.ir.renderables.base import Renderable
from blendify_core.ir.validate import as_bool, as_choice, as_float, strict_arguments
from blendify_core.typing import AnyArray

__all__ = ["export_gltf", "glb_bytes", "gltf_document", "LUMENS_PER_WATT", "Y_UP_ROTATION"]

LUMENS_PER_WATT = 683.0
#: the root node's rotation (x, y, z, w): -90 degrees about X takes the IR's +Z up to glTF's +Y up
Y_UP_ROTATION = (-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))

_FLOAT, _UINT32 = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_NEAREST, _LINEAR, _LINEAR_MIPMAP_LINEAR = 9728, 9729, 9987
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


class _Document:
    """The glTF JSON being built and its one binary buffer."""

    def __init__(self) -> None:
        self.gltf: dict[str, Any] = {
            "asset": {"version": "2.0", "generator": "blendify-core"},
            "scene": 0,
            "scenes": [{"name": "blendify", "nodes": []}],
            "nodes": [],
        }
        self.blob = bytearray()
        self.notes: list[str] = []
        self._cache: dict[Any, int] = {}

    def add(self, key: str, item: dict[str, Any]) -> int:
        items = self.gltf.setdefault(key, [])
        items.append(item)
        return len(items) - 1

    def use_extension(self, name: str) -> None:
        used = self.gltf.setdefault("extensionsUsed", [])
        if name not in used:
            used.append(name)

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    def view(self, data: bytes, target: int | None = None) -> int:
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        view: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.blob.extend(data)
        return self.add("bufferViews", view)

    def accessor(self, values: AnyArray, target: int | None = _ARRAY_BUFFER, key: Any = None) -> int:
        """An accessor over ``values`` (float -> FLOAT, integers -> UNSIGNED_INT), with min and max."""
        if key is not None and key in self._cache:
            return self._cache[key]
        arr = np.asarray(values)
        arr = arr.astype(np.uint32) if arr.dtype.kind in "iu" else arr.astype(np.float32)
        arr = np.ascontiguousarray(arr.reshape(len(arr), -1))
        comp = _UINT32 if arr.dtype == np.uint32 else _FLOAT
        item: dict[str, Any] = {
            "bufferView": self.view(arr.tobytes(), target),
            "componentType": comp,
            "count": int(arr.shape[0]),
            "type": _TYPES[arr.shape[1]],
        }
        if arr.shape[0]:
            cast = int if comp == _UINT32 else float
            item["min"] = [cast(x) for x in arr.min(axis=0)]
            item["max"] = [cast(x) for x in arr.max(axis=0)]
        index = self.add("accessors", item)
        if key is not None:
            self._cache[key] = index
        return index

    def image(self, pixels: AnyArray, key: Any) -> int:
        """A PNG image (uint8 (H, W, C), row 0 = top) stored in the buffer."""
        if key in self._cache:
            return self._cache[key]
        from PIL import Image

        arr = np.ascontiguousarray(pixels)
        if arr.shape[2] == 1:
            arr = arr[..., 0]
        out = io.BytesIO()
        Image.fromarray(arr).save(out, format="PNG")
        index = self.add("images", {"bufferView": self.view(out.getvalue()), "mimeType": "image/png"})
        self._cache[key] = index
        return index

    def texture(self, image: int, nearest: bool = False) -> int:
        key = ("texture", image, nearest)
        if key not in self._cache:
            filt = _NEAREST if nearest else _LINEAR
            sampler = self.add(
                "samplers", {"magFilter": filt, "minFilter": _NEAREST if nearest else _LINEAR_MIPMAP_LINEAR}
            )
            self._cache[key] = self.add("textures", {"source": image, "sampler": sampler})
        return self._cache[key]


# -- images ---------------------------------------------------------------------------------------------


def _srgb8(colors: TextureColors | FileTextureColors) -> AnyArray:
    """The colour texture as uint8 sRGB (what glTF's baseColorTexture holds), row 0 = top."""
    img = colors.image()
    if img.dtype == np.uint8 and colors.color_space == "srgb":
        return img
    rgba = colors.linear_rgba_image()
    out = linear_to_srgb8(rgba)
    out[..., 3] = np.round(np.clip(rgba[..., 3], 0, 1) * 255).astype(np.uint8)
    return out


def _data8(values: AnyArray) -> AnyArray:
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def _nearest_resize(values: AnyArray, shape: tuple[int, int]) -> AnyArray:
    if values.shape[:2] == shape:
        return values
    rows = (np.arange(shape[0]) * values.shape[0]) // shape[0]
    cols = (np.arange(shape[1]) * values.shape[1]) // shape[1]
    return values[rows[:, None], cols[None, :]]


# -- materials ------------------------------------------------------------------------------------------


def _material(doc: _Document, material: Any, colors: Any, texcoord: dict[int, int]) -> int:
    """The glTF material of one (material, colour source) slot; ``texcoord`` maps id(uv map) -> set index."""
    key = ("material", id(material), id(colors), tuple(sorted(texcoord.items())))
    if key in doc._cache:
        return doc._cache[key]
    pbr: dict[str, Any] = {}
    out: dict[str, Any] = {"pbrMetallicRoughness": pbr, "doubleSided": True}
    ext: dict[str, Any] = {}
    alpha = float(material.alpha)
    base = np.ones(4)
    if isinstance(colors, UniformColors):
        base = colors.linear_rgba.copy()
    elif isinstance(colors, (TextureColors, FileTextureColors)):
        image = doc.image(_srgb8(colors), ("colors", id(colors)))
        tex = doc.texture(image, nearest=colors.interpolation == "closest")
        pbr["baseColorTexture"] = {"index": tex, "texCoord": texcoord.get(id(colors.uv_map), 0)}
    base[3] *= alpha
    pbr["baseColorFactor"] = [float(x) for x in base]
    has_alpha = base[3] < 1.0 or bool(getattr(colors, "has_alpha", False))
    if has_alpha:
        out["alphaMode"] = "BLEND"
    uv_index = texcoord.get(-1, 0)  # the mesh's own UVs (data maps)
    if isinstance(material, GlossyBSDFMaterial):
        pbr["metallicFactor"], pbr["roughnessFactor"] = 1.0, float(material.get("roughness"))
        doc.note("GlossyBSDFMaterial: exported as a metal of the object's colour (metallic 1)")
    else:
        pbr["metallicFactor"], pbr["roughnessFactor"] = float(material.metallic), float(material.roughness)
        _metallic_roughness_map(doc, material, pbr, uv_index)
        _principled_extensions(doc, material, out, ext, uv_index)
    out["extras"] = {"blendify_material": type(material).__name__}
    if ext:
        out["extensions"] = ext
        for name in ext:
            doc.use_extension(name)
    index = doc.add("materials", out)
    doc._cache[key] = index
    return index


def _metallic_roughness_map(doc: _Document, material: Any, pbr: dict[str, Any], uv_index: int) -> None:
    rough: TextureMap | None = material.roughness_map
    metal: TextureMap | None = material.metallic_map
    if rough is None and metal is None:
        return
    maps = [m for m in (rough, metal) if m is not None]
    shape: tuple[int, int] = max(((m.values().shape[0], m.values().shape[1]) for m in maps), key=lambda s: s[0] * s[1])
    rgb = np.zeros(shape + (3,), dtype=np.uint8)
    # glTF: roughness in G, metallic in B; a channel without a map holds 1 and its factor the value
    rgb[..., 1] = _data8(_nearest_resize(rough.values(), shape)) if rough is not None else 255
    rgb[..., 2] = _data8(_nearest_resize(metal.values(), shape)) if metal is not None else 255
    if rough is not None:
        pbr["roughnessFactor"] = 1.0
    if metal is not None:
        pbr["metallicFactor"] = 1.0
    image = doc.image(rgb, ("metallic_roughness", id(rough), id(metal)))
    pbr["metallicRoughnessTexture"] = {"index": doc.texture(image), "texCoord": uv_index}


def _principled_extensions(
    doc: _Document, material: Any, out: dict[str, Any], ext: dict[str, Any], uv_index: int
) -> None:
    normal: NormalMap | None = material.normal_map
    if normal is not None:
        rgb = normal.image()
        rgb = rgb[..., :3] if rgb.dtype == np.uint8 else _data8(rgb[..., :3])
        if rgb.shape[2] == 1:
            rgb = np.repeat(rgb, 3, axis=2)
        image = doc.image(rgb, ("normal", id(normal)))
        out["normalTexture"] = {"index": doc.texture(image), "texCoord": uv_index, "scale": float(normal.strength)}
        if normal.strength != 1.0:
            doc.note("normal_map strength: glTF scales the normal's XY instead of Blender's blend")
    emission = material.linear("emission_color")[:3] * float(material.emission_strength)
    peak = float(emission.max())
    if peak > 0:
        out["emissiveFactor"] = [float(x) for x in emission / max(peak, 1.0)]
        if peak > 1.0:
            ext["KHR_materials_emissive_strength"] = {"emissiveStrength": peak}
    ext["KHR_materials_ior"] = {"ior": float(material.ior)}
    if material.transmission_weight > 0:
        ext["KHR_materials_transmission"] = {"transmissionFactor": float(material.transmission_weight)}
    if material.coat_weight > 0:
        ext["KHR_materials_clearcoat"] = {
            "clearcoatFactor": float(material.coat_weight),
            "clearcoatRoughnessFactor": float(material.coat_roughness),
        }
    if material.sheen_weight > 0:
        tint = material.linear("sheen_tint")[:3] * float(material.sheen_weight)
        ext["KHR_materials_sheen"] = {
            "sheenColorFactor": [float(x) for x in tint],
            "sheenRoughnessFactor": float(material.sheen_roughness),
        }
    level = float(material.specular_ior)
    if level != 0.5:
        # Blender's "Specular IOR Level": 0.5 keeps the IOR's reflectance, 0 removes it, 1 doubles it
        ext["KHR_materials_specular"] = {"specularFactor": min(2.0 * level, 1.0)}
        if level > 0.5:
            doc.note("specular_ior above 0.5: glTF's specularFactor stops at 1 (the IOR's own reflectance)")
    for name, label in (
        ("anisotropic", "anisotropy"),
        ("subsurface_weight", "subsurface scattering"),
        ("thin_film_thickness", "thin film"),
        ("diffuse_roughness", "diffuse roughness"),
    ):
        if float(getattr(material, name)) > 0:
            doc.note(f"{label}: not exported (no glTF equivalent)")
    if material.has_wireframe:
        doc.note("wireframe materials: exported as their surface (glTF has no wireframe)")


# -- geometry -------------------------------------------------------------------------------------------


def _uv_maps(r: Renderable) -> tuple[list[Any], UVMap | None]:
    """The UV maps to write: the mesh's own (``uv_map``, also read by data maps) and the colour textures'."""
    mesh_uv = r.uv_map if isinstance(r, Mesh) else None
    maps: list[Any] = [] if mesh_uv is None else [mesh_uv]
    for c in r.colors_list:
        if isinstance(c, (TextureColors, FileTextureColors)):
            maps.append(c.uv_map)
    unique: list[Any] = []
    for uv in maps:
        if all(uv is not u for u in unique):
            unique.append(uv)
    return unique, mesh_uv


def _mesh_node(doc: _Document, r: Renderable, points: str) -> dict[str, Any] | None:
    if isinstance(r, PointCloud):
        if r.num_vertices == 0:  # glTF accessors hold at least one element
            doc.note(f"PointCloud {r.tag!r}: no points, not exported")
            return None
        return _pointcloud_mesh(doc, r) if points == "points" else _sphere_cloud_mesh(doc, r)
    tm = r.to_mesh()
    if tm.is_empty:
        doc.note(f"{type(r).__name__} {r.tag!r}: no faces, not exported")
        return None
    faces = np.asarray(tm.faces, dtype=np.int64)
    uv_maps, mesh_uv = _uv_maps(r) if isinstance(r, Mesh) else ([], None)
    corner_uvs: dict[int, AnyArray] = {}  # id(uv map) or -2 (the tessellation's own UVs) -> (F, 3, 2)
    if isinstance(r, Mesh):
        for uv in uv_maps:
            corners = r.triangle_uvs(uv)
            if corners is not None:
                corner_uvs[id(uv)] = corners
    elif tm.uv is not None:
        corner_uvs[-2] = np.asarray(tm.uv)
    welded = all(isinstance(uv, VertexUV) for uv in uv_maps) and -2 not in corner_uvs
    v = np.asarray(tm.vertices, dtype=np.float64)
    normals = None if tm.normals is None else np.asarray(tm.normals, dtype=np.float64)
    if welded:
        positions, tri = v, faces
        gather: AnyArray | None = None
        uvs = {k: uv.data for k, uv in ((id(u), u) for u in uv_maps)}
    else:  # one vertex per triangle corner (per-corner UVs)
        gather = faces.reshape(-1)
        positions, tri = v[gather], np.arange(len(gather)).reshape(-1, 3)
        normals = None if normals is None else normals[gather]
        uvs = {k: c.reshape(-1, 2) for k, c in corner_uvs.items()}
    shared: dict[str, int] = {"POSITION": doc.accessor(positions)}
    if normals is not None:
        n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
        shared["NORMAL"] = doc.accessor(n)
    texcoord: dict[int, int] = {}
    for i, (k, uv) in enumerate(uvs.items()):
        flipped = np.stack([uv[:, 0], 1.0 - uv[:, 1]], axis=1)  # glTF's UV origin is the top-left
        shared[f"TEXCOORD_{i}"] = doc.accessor(flipped)
        texcoord[k] = i
    if mesh_uv is not None and id(mesh_uv) in texcoord:
        texcoord[-1] = texcoord[id(mesh_uv)]
    if -2 in texcoord:
        texcoord[-1] = texcoord[-2]
    fm = getattr(r, "faces_material", None)
    primitives = []
    for slot, (material, colors) in enumerate(zip(r.materials, r.colors_list)):
        sel = np.arange(len(tri)) if fm is None else np.flatnonzero(np.asarray(fm) == slot)
        if len(sel) == 0:
            continue
        attributes = dict(shared)
        if isinstance(colors, VertexColors):
            rgba = colors.linear_rgba
            attributes["COLOR_0"] = doc.accessor(rgba if gather is None else rgba[gather], key=("color", id(colors)))
        slot_texcoord = dict(texcoord)
        if isinstance(colors, (TextureColors, FileTextureColors)) and -2 in texcoord:
            slot_texcoord[id(colors.uv_map)] = texcoord[-2]
        primitives.append(
            {
                "attributes": attributes,
                "indices": doc.accessor(tri[sel].reshape(-1), _ELEMENT_ARRAY_BUFFER),
                "material": _material(doc, material, colors, slot_texcoord),
                "mode": 4,
            }
        )
    if isinstance(r, PlaneMesh) and r.shadow_catcher:
        doc.note("shadow catcher planes: exported as ordinary planes")
    return {"name": r.tag, "primitives": primitives}


def _pointcloud_mesh(doc: _Document, r: PointCloud) -> dict[str, Any]:
    colors = r.colors_list[0]
    attributes = {"POSITION": doc.accessor(r.vertices)}
    if isinstance(colors, VertexColors):
        attributes["COLOR_0"] = doc.accessor(colors.linear_rgba)
    size = r.point_size
    extras = {"point_size": float(np.mean(size))}  # the diameter (world units); the mean of per-point sizes
    if np.ndim(size):  # one per point: an application-specific attribute (glTF: names starting with "_")
        attributes["_POINT_SIZE"] = doc.accessor(np.asarray(size, dtype=np.float64)[:, None])
    doc.note(
        "point clouds: written as POINTS (glTF has no point size: the diameter is in the primitive's "
        "extras.point_size, per-point sizes in the _POINT_SIZE attribute)"
    )
    prim = {"attributes": attributes, "material": _material(doc, r.materials[0], colors, {}), "mode": 0}
    return {"name": r.tag, "primitives": [{**prim, "extras": extras}]}


def _sphere_cloud_mesh(doc: _Document, r: PointCloud) -> dict[str, Any]:
    tm = r.to_mesh()
    colors = r.colors_list[0]
    per_point = len(tm.vertices) // max(r.num_vertices, 1)
    attributes = {"POSITION": doc.accessor(tm.vertices)}
    if tm.normals is not None:
        attributes["NORMAL"] = doc.accessor(tm.normals)
    if isinstance(colors, VertexColors):
        attributes["COLOR_0"] = doc.accessor(np.repeat(colors.linear_rgba, per_point, axis=0))
    prim = {
        "attributes": attributes,
        "indices": doc.accessor(np.asarray(tm.faces).reshape(-1), _ELEMENT_ARRAY_BUFFER),
        "material": _material(doc, r.materials[0], colors, {}),
        "mode": 4,
    }
    return {"name": r.tag, "primitives": [prim]}


# -- nodes ----------------------------------------------------------------------------------------------


def _pose(obj: Any) -> dict[str, Any]:
    w, x, y, z = (float(q) for q in obj.quaternion)
    return {"translation": [float(t) for t in obj.translation], "rotation": [x, y, z, w]}


def _camera(doc: _Document, cam: Any) -> dict[str, Any]:
    w, h = int(cam.width), int(cam.height)
    extras: dict[str, Any] = {"resolution": [w, h]}
    if isinstance(cam, PerspectiveCamera):
        yfov = 2.0 * math.atan(h / (2.0 * cam.fy))
        aspect = (w / cam.fx) / (h / cam.fy)
        item: dict[str, Any] = {
            "type": "perspective",
            "perspective": {"yfov": yfov, "aspectRatio": aspect, "znear": float(cam.near), "zfar": float(cam.far)},
        }
        extras["K"] = cam.K.tolist()
        if abs(cam.cx - (w - 1) / 2.0) > 1e-6 or abs(cam.cy - (h - 1) / 2.0) > 1e-6:
            doc.note("camera: an off-centre principal point is not expressible in glTF (kept in extras.K)")
    elif not isinstance(cam, OrthographicCamera):
        raise UnsupportedFeatureError(f"glTF export: camera type {type(cam).__name__} has no glTF camera")
    else:
        xmag = float(cam.ortho_scale) / 2.0
        item = {
            "type": "orthographic",
            "orthographic": {"xmag": xmag, "ymag": xmag * h / w, "znear": float(cam.near), "zfar": float(cam.far)},
        }
    if cam.distortion is not None:
        doc.note("camera: lens distortion is not expressible in glTF")
    item["name"] = cam.tag
    index = doc.add("cameras", item)
    return {"name": cam.tag, "camera": index, **_pose(cam), "extras": extras}


def _light(doc: _Document, light: Any, lumens_per_watt: float) -> dict[str, Any]:
    color = [float(c) for c in np.clip(light.linear_color, 0.0, None)]
    extras = {"blendify_light": type(light).__name__, "strength": float(light.strength)}
    item: dict[str, Any] = {"name": light.tag, "color": color}
    if isinstance(light, SunLight):
        item.update(type="directional", intensity=float(light.strength) * lumens_per_watt)
        extras["unit"] = "W/m^2"
    elif isinstance(light, SpotLight):
        outer, inner = spot_cone(light.spot_size, light.spot_blend)
        item.update(
            type="spot",
            intensity=point_intensity(light.strength) * lumens_per_watt,
            spot={"innerConeAngle": float(min(inner, outer)), "outerConeAngle": float(min(outer, math.pi / 2))},
        )
        extras["unit"] = "W"
        if outer > math.pi / 2:
            doc.note("spot lights wider than 180 degrees: glTF's cone stops at 90 degrees half-angle")
    elif isinstance(light, AreaLight):
        item.update(
            type="spot",
            intensity=float(light.strength) / math.pi * lumens_per_watt,
            spot={"innerConeAngle": 0.0, "outerConeAngle": math.pi / 2},
        )
        extras.update(unit="W", shape=light.shape, size=[float(s) for s in light.size])
        doc.note("area lights: written as 90-degree spot lights of the emitter's on-axis intensity")
    elif not isinstance(light, PointLight):
        raise UnsupportedFeatureError(f"glTF export: light type {type(light).__name__} has no glTF light")
    else:
        item.update(type="point", intensity=point_intensity(light.strength) * lumens_per_watt)
        extras["unit"] = "W"
    ext = doc.gltf.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
    ext["lights"].append(item)
    doc.use_extension("KHR_lights_punctual")
    node = {"name": light.tag, **_pose(light), "extensions": {"KHR_lights_punctual": {"light": len(ext["lights"]) - 1}}}
    return {**node, "extras": extras}


def gltf_document(
    scene: Any, y_up: bool = True, points: str = "points", lumens_per_watt: float = LUMENS_PER_WATT
) -> tuple[dict[str, Any], bytes, list[str]]:
    """The glTF JSON of ``scene``, its binary buffer (not yet referenced by a URI) and the approximation
    notes. See :func:`export_gltf` for the arguments."""
    y_up = as_bool("y_up", y_up)
    points = as_choice("points", points, ("points", "spheres"))
    lumens_per_watt = as_float("lumens_per_watt", lumens_per_watt, min_value=0.0, exclusive_min=True)
    doc = _Document()
    children: list[int] = []
    for r in scene.renderables:
        mesh = _mesh_node(doc, r, points)
        if mesh is None:
            continue
        node = {"name": r.tag, "mesh": doc.add("meshes", mesh), **_pose(r), "extras": {"blendify_tag": r.tag}}
        children.append(doc.add("nodes", node))
        if not r.emit_shadows:
            doc.note("emit_shadows=False: not expressible in glTF")
    for light in scene.lights:
        children.append(doc.add("nodes", _light(doc, light, lumens_per_watt)))
    if scene.lights.background is not None or scene.lights.environment is not None:
        doc.note("the world light (background / environment map): not expressible in glTF")
    if scene.camera is not None:
        children.append(doc.add("nodes", _camera(doc, scene.camera)))
    root: dict[str, Any] = {"name": GLTF_ROOT, "children": children}
    if y_up:
        root["rotation"] = list(Y_UP_ROTATION)
    doc.gltf["scenes"][0]["nodes"] = [doc.add("nodes", root)]
    if doc.notes:
        doc.gltf["asset"]["extras"] = {"blendify_approximations": list(doc.notes)}
    doc.blob.extend(b"\0" * (-len(doc.blob) % 4))
    if doc.blob:
        doc.gltf["buffers"] = [{"byteLength": len(doc.blob)}]
    return doc.gltf, bytes(doc.blob), list(doc.notes)


def glb_bytes(gltf: dict[str, Any], blob: bytes) -> bytes:
    """The binary glTF container (.glb) of a glTF JSON and its buffer."""
    text = json.dumps(gltf, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), _JSON_CHUNK) + text
    if blob:
        chunks += struct.pack("<II", len(blob), _BIN_CHUNK) + blob
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


@strict_arguments
def export_gltf(
    scene: Any,
    path: str | os.PathLike[str],
    y_up: bool = True,
    points: str = "points",
    lumens_per_watt: float = LUMENS_PER_WATT,
) -> Path:
    """Write ``scene`` as glTF 2.0: one binary ``.glb`` file, or a ``.gltf`` JSON file with its buffer
    (geometry and PNG textures) in ``<name>.bin`` beside it. ``y_up``: rotate the IR's +Z-up world to
    glTF's +Y up under the root node (default; False keeps the IR's axes). ``points``: point clouds as
    ``"points"`` (POINTS primitives) or ``"spheres"`` (the tessellated spheres the renders show).
    ``lumens_per_watt`` converts light power to the photometric units of ``KHR_lights_punctual``.
    Files are written atomically; what glTF cannot express is listed in one warning and in
    ``asset.extras["blendify_approximations"]``. Returns the written path."""
    p = Path(os.fspath(path)).expanduser()
    suffix = p.suffix.lower()
    if suffix not in (".glb", ".gltf"):
        raise InvalidSceneError(f"path: expected a .glb or .gltf file name, got {str(path)!r}")
    gltf, blob, notes = gltf_document(scene, y_up=y_up, points=points, lumens_per_watt=lumens_per_watt)
    if suffix == ".glb":
        data = glb_bytes(gltf, blob)
        out = atomic_write(p, lambda tmp: Path(tmp).write_bytes(data))
    else:
        if blob:
            bin_name = p.with_suffix(".bin").name
            gltf["buffers"][0]["uri"] = bin_name
            atomic_write(p.with_suffix(".bin"), lambda tmp: Path(tmp).write_bytes(blob))
        text = json.dumps(gltf, indent=1)
        out = atomic_write(p, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    if notes:
        warnings.warn(f"export {out.name}: approximations: " + "; ".join(notes), UserWarning, stacklevel=3)
    return out
