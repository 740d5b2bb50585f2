"""Evaluated objects of a .blend -> IR meshes and point clouds (keyword arguments of ``add_mesh`` /
``add_pointcloud``).

- meshes and everything that converts to a mesh (curves, surfaces, text, metaballs, geometry-nodes
  output, collection and particle instances), evaluated through the depsgraph (by :mod:`.attach`),
  triangulated, with the instance's world transform (scale and shear baked into the object-space
  vertices, rotation and translation kept as the pose); vertices are split where Blender's corner
  normals (sharp edges, flat faces) or corner colours differ, so smooth/flat shading is kept;
- native point clouds (e.g. Geometry Nodes Mesh to Points) -> PointCloud (per-point radius and colour
  attribute, emission from the colour -> ``particle_emission_strength``);
- UV layers -> FacesUV; colour attributes read by the material -> VertexColors (linear); image textures
  -> FileTextureColors (a file) or TextureColors (pixels); per-face materials.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes, decompose, is_identity, rgb01
from blendify_blender.blendfile.nodes import MaterialReader
from blendify_core.ir.colors import (
    FacesUV,
    FileTextureColors,
    TextureColors,
    UniformColors,
    VertexColors,
    load_image,
)

__all__ = ["MESH_TYPES", "mesh_spec", "points_spec"]

#: object types parsed through ``to_mesh()``
MESH_TYPES = ("MESH", "CURVE", "SURFACE", "META", "FONT")


def mesh_spec(materials: MaterialReader, bpy_obj: Any, matrix: np.ndarray, name: str) -> dict[str, Any] | None:
    """The ``add_mesh`` keywords of one evaluated object instance (anything convertible to a mesh), or
    None when it has no faces or cannot be converted (noted)."""
    try:
        me = bpy_obj.to_mesh()
    except RuntimeError as exc:
        materials.notes.add(f"object {name!r}: cannot convert to a mesh ({exc})")
        return None
    if me is None:
        return None
    try:
        return _MeshReader(materials, bpy_obj, me, name).spec(matrix)
    finally:
        bpy_obj.to_mesh_clear()


def _foreach(coll: Any, attr: str, n: int, dtype: Any) -> np.ndarray:
    out = np.empty(n, dtype=dtype)
    coll.foreach_get(attr, out)
    return out


@dataclass
class _Triangles:
    """A mesh's loop triangles: per-vertex positions and per-triangle indices."""

    verts: np.ndarray  # (nv, 3) float64 object-space positions
    vertices: np.ndarray  # (nt, 3) int32 vertex indices
    loops: np.ndarray  # (nt, 3) int32 corner (loop) indices
    polygons: np.ndarray  # (nt,) int32 face (polygon) index
    material: np.ndarray  # (nt,) int32 material slot index


class _MeshReader:
    """One evaluated mesh -> ``add_mesh`` keywords; :meth:`spec` runs the steps in order."""

    t: _Triangles  # set by spec()

    def __init__(self, materials: MaterialReader, bpy_obj: Any, me: Any, name: str) -> None:
        self.materials = materials
        self.notes: Notes = materials.notes
        self.baker = materials.baker
        self.obj = bpy_obj
        self.me = me
        self.name = name
        self.where = f"object {name!r}"
        self._attrs: dict[str, tuple[str, np.ndarray] | None] = {}
        self._uv_cache: dict[str, FacesUV] = {}

    def spec(self, matrix: np.ndarray) -> dict[str, Any] | None:
        t = self._read_triangles()
        if t is None:
            return None
        self.t = t
        mats, faces_material = self._slot_materials()
        smooth, keys = self._shading_keys()
        keys += self._color_keys(mats)
        faces, verts, src_corner = self._split_vertices(keys)
        colors = [self._colors(col, len(verts), src_corner) for _m, col in mats]
        if self.baker is not None:  # bumped / procedural normals: this object's normal map, baked
            for i, (m, col) in enumerate(mats):
                if not (col.get("bake_normal") or col.get("bake_maps")):
                    continue
                mats[i] = (m.copy(), col)  # this object's own copy: its maps follow its UVs
                if col.get("bake_normal"):
                    self.baker.request_normal(self.obj, mats[i][0], col["bake_normal"], self.where)
                for param, names in col.get("bake_maps", ()):
                    self.baker.request_map(self.obj, col["material"], names, mats[i][0], param, self.where)
        return self._posed(matrix, verts, faces, [m for m, _c in mats], colors, faces_material, smooth)

    def _read_triangles(self) -> _Triangles | None:
        me = self.me
        me.calc_loop_triangles()
        nv, nt = len(me.vertices), len(me.loop_triangles)
        if nv == 0 or nt == 0:
            if nv:
                self.notes.add(f"{self.where}: {nv} vertices without faces (edges/points) skipped")
            return None
        tris = me.loop_triangles
        return _Triangles(
            verts=_foreach(me.vertices, "co", nv * 3, np.float32).reshape(nv, 3).astype(np.float64),
            vertices=_foreach(tris, "vertices", nt * 3, np.int32).reshape(nt, 3),
            loops=_foreach(tris, "loops", nt * 3, np.int32).reshape(nt, 3),
            polygons=_foreach(tris, "polygon_index", nt, np.int32),
            material=_foreach(tris, "material_index", nt, np.int32),
        )

    def _slot_materials(self) -> tuple[list[tuple[Any, dict[str, Any]]], np.ndarray | None]:
        """(IR material, per-mesh colour description) of each used slot (object slots win over mesh
        slots), and the per-face index into that list (None for a single material)."""
        obj, me = self.obj, self.me
        slots = [s.material for s in obj.material_slots] if len(obj.material_slots) else list(me.materials)
        if not slots:
            slots = [None]
        tm = np.clip(self.t.material, 0, len(slots) - 1)
        used = np.unique(tm)
        remap = np.full(len(slots), -1, dtype=np.int32)
        remap[used] = np.arange(len(used), dtype=np.int32)
        mats = []
        for i in used:
            m_ir, col_desc = self.materials.cached(slots[i], self.where)
            col_desc = dict(col_desc)  # per-mesh copy (attribute names are resolved per mesh)
            if col_desc.pop("emission_from_color", 0.0):
                self.notes.add(f"{self.where}: emission driven by the base colour is only parsed on point clouds")
            mats.append((m_ir, col_desc))
        return mats, (remap[tm] if len(used) > 1 else None)

    def _shading_keys(self) -> tuple[bool, list[np.ndarray]]:
        """Whether any face is smooth, and the per-corner keys that decide vertex splitting: the vertex
        index, plus the corner normal when corner normals differ from vertex normals (sharp edges, flat
        faces among smooth ones)."""
        me, t = self.me, self.t
        smooth_face = _foreach(me.polygons, "use_smooth", len(me.polygons), bool)
        keys: list[np.ndarray] = [t.vertices.reshape(-1, 1).astype(np.int64)]
        smooth = bool(smooth_face.any())
        if smooth:
            nl, nv = len(me.loops), len(t.verts)
            cn = _foreach(me.corner_normals, "vector", nl * 3, np.float32).reshape(nl, 3)[t.loops.ravel()]
            vn = _foreach(me.vertex_normals, "vector", nv * 3, np.float32).reshape(nv, 3)[t.vertices.ravel()]
            if np.max(np.abs(cn - vn)) > 1e-4:
                keys.append(np.round(cn.astype(np.float64) * 1e3).astype(np.int64))
        return smooth, keys

    def _color_keys(self, mats: list[tuple[Any, dict[str, Any]]]) -> list[np.ndarray]:
        """Read the colour attributes the materials use; per-corner keys for those not on vertices."""
        me = self.me
        corner_names: list[str] = []
        for _mat, col in mats:
            if col["kind"] != "attribute":
                continue
            nm = col["name"] or me.color_attributes.default_color_name or me.color_attributes.active_color_name
            col["name"] = nm
            if nm not in self._attrs:
                self._attrs[nm] = read_color_attribute(me, nm, self.where, self.notes)
            got = self._attrs[nm]
            if got is not None and got[0] != "POINT" and nm not in corner_names:
                corner_names.append(nm)
        return [np.round(self._per_corner(nm).astype(np.float64) * 1e5).astype(np.int64) for nm in corner_names]

    def _per_corner(self, nm: str) -> np.ndarray:
        """A colour attribute's value at every triangle corner, (3 nt, 4)."""
        dom, data = self._attrs[nm]  # type: ignore[misc]
        if dom == "POINT":
            return data[self.t.vertices.ravel()]
        if dom == "CORNER":
            return data[self.t.loops.ravel()]
        return np.repeat(data[self.t.polygons], 3, axis=0)  # FACE

    def _split_vertices(self, keys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(faces, vertices, source corner of each output vertex or None): a vertex keeps its index for
        its first (normal, colour) variant; other variants become new vertices appended at the end."""
        t = self.t
        if len(keys) == 1:
            return t.vertices.astype(np.int32), t.verts, None
        nv, nt = len(t.verts), len(t.vertices)
        corner_vertex = t.vertices.ravel()
        keymat = np.concatenate(keys, axis=1)
        _u, first, inverse = np.unique(keymat, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.ravel()
        key_vertex = corner_vertex[first]
        order = np.lexsort((first, key_vertex))
        primary = np.zeros(len(first), dtype=bool)
        sv = key_vertex[order]
        primary[order[np.r_[True, sv[1:] != sv[:-1]]]] = True
        new_id = np.empty(len(first), dtype=np.int64)
        new_id[primary] = key_vertex[primary]
        extra = np.flatnonzero(~primary)
        extra = extra[np.argsort(first[extra])]
        new_id[extra] = nv + np.arange(len(extra))
        new_faces = new_id[inverse].reshape(nt, 3).astype(np.int32)
        new_verts = np.concatenate([t.verts, t.verts[key_vertex[extra]]], axis=0)
        src_corner = np.full(len(new_verts), -1, dtype=np.int64)
        src_corner[new_id] = first
        return new_faces, new_verts, src_corner

    def _vertex_values(self, nm: str, n_out: int, src_corner: np.ndarray | None) -> np.ndarray:
        """A colour attribute per output vertex, (n_out, 4)."""
        dom, data = self._attrs[nm]  # type: ignore[misc]
        nv = len(self.t.verts)
        if dom == "POINT" and (src_corner is None or n_out == nv):
            return data
        out = np.ones((n_out, 4), dtype=np.float32)
        if dom == "POINT":
            out[:nv] = data
        if src_corner is None:
            out[self.t.vertices.ravel()] = self._per_corner(nm)
            return out
        ok = src_corner >= 0
        out[ok] = self._per_corner(nm)[src_corner[ok]]
        return out

    def _faces_uv(self, layer: str) -> FacesUV | None:
        """The named UV layer ('' or missing: the render UV layer) per triangle corner, or None."""
        me = self.me
        lay = None
        if layer:
            lay = me.uv_layers.get(layer)
            if lay is None:
                self.notes.add(f"{self.where}: UV map {layer!r} not found, used the render UV map")
        if lay is None:
            lay = next((u for u in me.uv_layers if u.active_render), None) or me.uv_layers.active
        if lay is None:
            return None
        if lay.name not in self._uv_cache:
            uv = _foreach(lay.uv, "vector", len(me.loops) * 2, np.float32)
            self._uv_cache[lay.name] = FacesUV(uv.reshape(-1, 2)[self.t.loops])
        return self._uv_cache[lay.name]

    def _colors(self, col: dict[str, Any], n_out: int, src_corner: np.ndarray | None) -> Any:
        """The IR colour source of one material's colour description (uniform when the source is unusable)."""
        c = None
        if col["kind"] == "bake" and self.baker is not None and col.get("material") is not None:
            rgb, _k = rgb01(np.asarray(col["rgba"], dtype=np.float64)[:3])
            c = UniformColors(tuple(rgb), color_space="linear")  # replaced by the baked texture
            self.baker.request(self.obj, col["material"], col["node"], col["socket"], c, col["where"])
            return c
        if col["kind"] == "texture":
            c = self._texture_colors(col)
        elif col["kind"] == "attribute":
            c = self._attribute_colors(col, n_out, src_corner)
        if c is None:
            rgba = np.asarray(col.get("rgba", (0.8, 0.8, 0.8, 1.0)), dtype=np.float64)
            rgb, k = rgb01(rgba[:3])
            if k > 1.0:
                self.notes.add(f"{self.where}: base colour > 1 normalised to [0, 1]")
            # the 4th component of a Base Color socket does not affect shading (Alpha is its own input)
            c = UniformColors(tuple(rgb), color_space="linear")
        return c

    def _texture_colors(self, col: dict[str, Any]) -> Any:
        uvm = self._faces_uv(col["uv"])
        if uvm is None:
            self.notes.add(f"{self.where}: image texture without a UV map, used a uniform colour")
            return None
        transform = col.get("uv_transform")
        if transform is not None:  # a Mapping node: an affine transform of the UVs
            uv = np.asarray(uvm.data, dtype=np.float64)
            uvm = FacesUV(uv @ transform[:, :2].T + transform[:, 2])
        kind, data, cs = col["image"]
        if col.get("opaque"):
            kind, data = _opaque_image(kind, data)
        if kind == "file":
            return FileTextureColors(data, uvm, color_space=cs, interpolation=col["interpolation"])
        return TextureColors(data, uvm, color_space=cs, interpolation=col["interpolation"])

    def _attribute_colors(self, col: dict[str, Any], n_out: int, src_corner: np.ndarray | None) -> Any:
        if self._attrs.get(col["name"]) is None:
            self.notes.add(f"{self.where}: colour attribute {col['name']!r} not found, used white")
            return UniformColors((1.0, 1.0, 1.0), color_space="linear")
        vals = self._vertex_values(col["name"], n_out, src_corner)
        if float(vals[:, :3].max(initial=0.0)) > 1.0 or float(vals.min(initial=0.0)) < 0.0:
            self.notes.add(f"{self.where}: colour attribute {col['name']!r} clipped to [0, 1]")
        vals = np.clip(vals, 0.0, 1.0)
        return VertexColors(vals[:, :3] if col.get("opaque") else vals, color_space="linear")

    def _posed(
        self,
        matrix: np.ndarray,
        verts: np.ndarray,
        faces: np.ndarray,
        mats: list[Any],
        colors: list[Any],
        faces_material: np.ndarray | None,
        smooth: bool,
    ) -> dict[str, Any]:
        """The world transform: rotation + translation as the pose, scale/shear/reflection baked in (a
        reflection flips the winding and the UV corners)."""
        r, s, t = decompose(matrix)
        if not is_identity(s):
            verts = verts @ s.T
            if np.linalg.det(s) < 0:
                faces = faces[:, ::-1].copy()
                colors = [_flip_uv_colors(c) for c in colors]
        uv_default = self._faces_uv("") if len(self.me.uv_layers) else None
        if uv_default is not None and np.linalg.det(s) < 0:
            uv_default = FacesUV(uv_default.data[:, ::-1])
        uv_map = self._mesh_uv(uv_default, colors, mats)
        return {
            "vertices": verts,
            "faces": faces,
            "material": mats if len(mats) > 1 else mats[0],
            "colors": colors if len(colors) > 1 else colors[0],
            "faces_material": faces_material,
            "uv_map": uv_map,
            "smooth": smooth,
            "rotation_mode": "rotmat",
            "rotation": r,
            "translation": t,
        }

    def _mesh_uv(self, uv_default: Any, colors: list[Any], mats: list[Any]) -> Any:
        """The mesh's UV map: the render UV layer, or the UVs of the image textures when they read another
        layer or go through a Mapping node (the renderers read every texture through the mesh's UVs)."""
        tex = [c.uv_map for c in colors if isinstance(c, (TextureColors, FileTextureColors))]
        other = []
        for uv in tex:
            same = uv_default is not None and np.array_equal(uv.data, uv_default.data)
            if not same and not any(np.array_equal(uv.data, o.data) for o in other):
                other.append(uv)
        if not other:
            return uv_default
        if len(other) > 1:
            self.notes.add(f"{self.where}: image textures on several UV maps / mappings: all read through the first")
        if any(
            m.get(k) is not None
            for m in mats
            for k in ("roughness_map", "metallic_map", "normal_map")
            if k in m.parameter_names()
        ):
            self.notes.add(f"{self.where}: roughness / metallic / normal maps read through the base colour's UVs")
        return other[0]


def read_color_attribute(me: Any, nm: str, where: str, notes: Notes) -> tuple[str, np.ndarray] | None:
    """(domain, (n, 4) float32 linear RGBA) of a colour-like attribute, or None (missing or not a colour)."""
    attr = me.attributes.get(nm) if nm else None
    if attr is None:
        return None
    if attr.domain not in ("POINT", "CORNER", "FACE"):
        notes.add(f"{where}: colour attribute {nm!r} on the {attr.domain} domain not supported")
        return None
    n = len(attr.data)
    if attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
        buf = _foreach(attr.data, "color", n * 4, np.float32)  # scene-linear for both storage types
        return attr.domain, buf.reshape(n, 4)
    if attr.data_type == "FLOAT_VECTOR":
        buf = _foreach(attr.data, "vector", n * 3, np.float32)
        return attr.domain, np.concatenate([buf.reshape(n, 3), np.ones((n, 1), np.float32)], axis=1)
    if attr.data_type == "FLOAT":
        buf = _foreach(attr.data, "value", n, np.float32)
        return attr.domain, np.concatenate([np.repeat(buf[:, None], 3, axis=1), np.ones((n, 1), np.float32)], 1)
    notes.add(f"{where}: attribute {nm!r} of type {attr.data_type} is not a colour")
    return None


def _opaque_image(kind: str, data: Any) -> tuple[str, Any]:
    """An image whose alpha Blender does not use: files with a real alpha channel are read and their
    RGB kept in memory (the IR would otherwise make the surface transparent)."""
    img = load_image(data) if kind == "file" else data
    if img.shape[2] != 4:
        return kind, data
    full = 255 if img.dtype == np.uint8 else 1.0
    if kind == "file" and bool(np.all(img[..., 3] >= full)):
        return kind, data
    return "pixels", np.ascontiguousarray(img[..., :3])


def _flip_uv_colors(c: Any) -> Any:
    if isinstance(c, FileTextureColors):
        return FileTextureColors(c.texture_path, FacesUV(c.uv_map.data[:, ::-1]), c.color_space, c.interpolation)
    if isinstance(c, TextureColors):
        return TextureColors(c.texture, FacesUV(c.uv_map.data[:, ::-1]), c.color_space, c.interpolation)
    return c


# ---------------------------------------------------------------------------------------------------
# point clouds
# ---------------------------------------------------------------------------------------------------


def points_spec(materials: MaterialReader, bpy_obj: Any, matrix: np.ndarray, name: str) -> dict[str, Any] | None:
    """A point cloud (native points, e.g. Geometry Nodes Mesh to Points) -> ``add_pointcloud`` keywords
    (None when it has no point left)."""
    notes = materials.notes
    pc = bpy_obj.data
    attrs = pc.attributes
    n = len(attrs["position"].data) if "position" in attrs else 0
    if n == 0:
        return None
    verts = _foreach(attrs["position"].data, "vector", n * 3, np.float32).reshape(n, 3).astype(np.float64)
    if "radius" in attrs:
        rad = _foreach(attrs["radius"].data, "value", n, np.float32)
    else:
        rad = np.full(n, 0.01, dtype=np.float32)
    slots = [s.material for s in bpy_obj.material_slots] if len(bpy_obj.material_slots) else list(pc.materials)
    mat = slots[0] if slots else None
    if len(slots) > 1:
        notes.add(f"point cloud {name!r}: {len(slots)} materials, used the first")
    m_ir, col = materials.cached(mat, f"point cloud {name!r}")
    col = dict(col)
    emission = float(col.pop("emission_from_color", 0.0))
    colors = _point_colors(pc, col, n, name, notes)
    r, s, t = decompose(matrix)
    if not is_identity(s):
        verts = verts @ s.T
        scale = abs(np.linalg.det(s)) ** (1.0 / 3.0)
        rad = rad * scale
        if not np.allclose(np.linalg.svd(s, compute_uv=False), scale, rtol=1e-5):
            notes.add(f"point cloud {name!r}: non-uniform scale, sphere radii scaled by the mean")
    size = 2.0 * rad.astype(np.float64)
    if np.any(size <= 0):
        notes.add(f"point cloud {name!r}: points with radius <= 0 dropped")
        keep = size > 0
        verts, size = verts[keep], size[keep]
        if isinstance(colors, VertexColors):
            colors = VertexColors(colors.vertex_colors[keep], color_space="linear")
        if len(verts) == 0:
            return None
    point_size: Any = float(size[0]) if np.allclose(size, size[0], rtol=1e-6) else size
    return {
        "vertices": verts,
        "material": m_ir,
        "colors": colors,
        "point_size": point_size,
        "particle_emission_strength": emission,
        "rotation_mode": "rotmat",
        "rotation": r,
        "translation": t,
    }


def _point_colors(pc: Any, col: dict[str, Any], n: int, name: str, notes: Notes) -> Any:
    """Per-point colours from a point-domain colour attribute, else the uniform base colour."""
    if col["kind"] == "attribute":
        nm = col["name"] or pc.color_attributes.default_color_name or pc.color_attributes.active_color_name
        attr = pc.attributes.get(nm) if nm else None
        if attr is not None and attr.domain == "POINT" and attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
            buf = _foreach(attr.data, "color", n * 4, np.float32)
            return VertexColors(np.clip(buf.reshape(n, 4), 0.0, 1.0), color_space="linear")
        notes.add(f"point cloud {name!r}: colour attribute {nm!r} not found, used white")
    elif col["kind"] == "texture":
        notes.add(f"point cloud {name!r}: image textures on points not supported, used a uniform colour")
    rgba = np.asarray(col.get("rgba", (0.8, 0.8, 0.8, 1.0)), dtype=np.float64)
    rgb, _k = rgb01(rgba[:3])
    return UniformColors(tuple(rgb), color_space="linear")
