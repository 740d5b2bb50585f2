"""trimesh interop: add ``trimesh.Trimesh``, ``trimesh.Scene``, ``trimesh.PointCloud`` objects or mesh files
(OBJ, PLY, GLB/glTF, STL, OFF) to a scene, keeping vertex colours, UVs, textures and material groups."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import Colors, TextureColors, UniformColors, VertexColors, VertexUV
from blendify_core.ir.materials import Material, PrincipledBSDFMaterial
from blendify_core.ir.validate import _describe, as_bool
from blendify_core.typing import AnyArray

__all__ = ["add_trimesh", "load_trimesh"]

SUFFIXES = (".obj", ".ply", ".glb", ".gltf", ".stl", ".off")
_DEFAULT_COLOR = (0.8, 0.8, 0.8)
_NAME_KEY = "blendify_name"  # the geometry's name in a trimesh.Scene, kept in its metadata
#: the root node blendify's glTF export hangs a scene under, and its rotation from the IR's +Z up to glTF's
#: +Y up ((x, y, z) -> (x, z, -y)): reading such a file undoes it, so an exported scene comes back as it was
GLTF_ROOT = "blendify_scene"
GLTF_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def load_trimesh(path: str | os.PathLike[str]) -> Any:
    """Load a mesh file with trimesh (``process=False``: vertex order and count are kept)."""
    import trimesh

    p = Path(path).expanduser()
    if not p.is_file():
        raise InvalidSceneError(f"mesh_or_path: no such file {str(p)!r}")
    if p.suffix.lower() not in SUFFIXES:
        raise InvalidSceneError(f"mesh_or_path: expected one of {list(SUFFIXES)} files, got {p.name!r}")
    try:
        return trimesh.load(str(p), process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise InvalidSceneError(f"mesh_or_path: cannot read {str(p)!r} ({type(exc).__name__}: {exc})") from None


def _material_of(visual: Any) -> Material:
    mat = getattr(visual, "material", None)
    if mat is not None and type(mat).__name__ == "PBRMaterial":
        rough = mat.roughnessFactor if mat.roughnessFactor is not None else 0.5
        metal = mat.metallicFactor if mat.metallicFactor is not None else 0.0
        return PrincipledBSDFMaterial(roughness=float(np.clip(rough, 0, 1)), metallic=float(np.clip(metal, 0, 1)))
    return PrincipledBSDFMaterial()


def _image_of(material: Any) -> Any:
    for attr in ("image", "baseColorTexture"):
        img = getattr(material, attr, None)
        if img is not None:
            return img
    return None


def _part(mesh: Any) -> tuple[AnyArray, AnyArray, Any]:
    """(vertices, faces, colour description) of one trimesh.Trimesh.

    The colour description is ("uniform", rgba) | ("vertex", (N,4) float) | ("texture", image uint8, uv (N,2))."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    visual = mesh.visual
    kind = getattr(visual, "kind", None)
    if kind == "texture":
        img = _image_of(visual.material)
        uv = getattr(visual, "uv", None)
        if img is not None and uv is not None and len(uv) == len(v):
            arr = np.asarray(img.convert("RGBA") if img.mode not in ("RGB", "RGBA") else img)
            factor = getattr(visual.material, "baseColorFactor", None)
            if factor is not None and np.any(np.asarray(factor)[:3] < 255):
                f_lin = np.asarray(factor, dtype=np.float64) / 255.0
                arr = np.clip(arr.astype(np.float64) * f_lin[: arr.shape[2]], 0, 255).astype(np.uint8)
            return v, f, ("texture", arr, np.asarray(uv, dtype=np.float64))
        color = np.asarray(visual.material.main_color, dtype=np.float64) / 255.0
        vc = getattr(visual, "vertex_attributes", {}).get("color")  # glTF COLOR_0 next to a material
        if vc is not None and len(vc) == len(v):
            vc = np.asarray(vc)
            vc = vc / 255.0 if vc.dtype == np.uint8 else vc / 65535.0 if vc.dtype == np.uint16 else vc
            rgba = np.ones((len(v), 4))
            rgba[:, : vc.shape[1]] = vc
            return v, f, ("vertex", rgba * color[None, : rgba.shape[1]])  # glTF: COLOR_0 x baseColorFactor
        return v, f, ("uniform", color)
    if kind == "vertex":
        vc = np.asarray(visual.vertex_colors, dtype=np.float64) / 255.0
        return v, f, ("vertex", vc)
    if kind == "face":
        fc = np.asarray(visual.face_colors, dtype=np.float64) / 255.0
        v2 = v[f].reshape(-1, 3)
        f2 = np.arange(len(v2)).reshape(-1, 3)
        return v2, f2, ("vertex", np.repeat(fc, 3, axis=0))
    return v, f, ("uniform", np.array(_DEFAULT_COLOR + (1.0,)))


def _dump(scene: Any) -> list[Any]:
    """The scene's geometries in world space (``Scene.dump``, but keeping the vertex colours trimesh
    stores beside a glTF material, which its copies drop)."""
    out = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry[name]
        moved = geometry.copy()
        moved.apply_transform(transform)
        color = getattr(getattr(geometry, "visual", None), "vertex_attributes", {}).get("color")
        if color is not None and hasattr(moved.visual, "vertex_attributes"):
            moved.visual.vertex_attributes["color"] = np.asarray(color).copy()
        moved.metadata[_NAME_KEY] = name
        out.append(moved)
    return out


def _undo_blendify_y_up(scene: Any) -> None:
    """Rotate a scene read from blendify's own glTF export back to +Z up (its root node says so)."""
    if GLTF_ROOT not in scene.graph.nodes:
        return
    matrix = np.asarray(scene.graph.get(GLTF_ROOT)[0], dtype=np.float64)
    if np.allclose(matrix[:3, :3], GLTF_Y_UP, atol=1e-9):
        undo = np.eye(4)
        undo[:3, :3] = GLTF_Y_UP.T
        scene.apply_transform(undo)


def _tagged(collection: Any, geometry: Any, keywords: dict[str, Any]) -> dict[str, Any]:
    """``keywords`` with the geometry's name in the file as the tag (e.g. a glTF mesh name), unless a tag
    is given or the name is taken."""
    name = geometry.metadata.get(_NAME_KEY)
    if "tag" in keywords or not isinstance(name, str) or not name or name in collection:
        return keywords
    return {**keywords, "tag": name}


def _colors(desc: Any, n_total: int, offset: int, n: int, color_space: str = "srgb") -> Colors:
    """The colour source of one part; ``color_space`` is how the file stores vertex and factor colours
    (glTF: linear; textures are always sRGB images)."""
    kind = desc[0]
    if kind == "uniform":
        rgba = np.clip(desc[1], 0, 1)
        return UniformColors(rgba if rgba[3] < 1 else rgba[:3], color_space=color_space)
    if kind == "vertex":
        vc = np.zeros((n_total, 4))
        vc[:, 3] = 1.0
        vc[offset : offset + n] = np.clip(desc[1], 0, 1)
        return VertexColors(vc if np.any(vc[:, 3] < 1) else vc[:, :3], color_space=color_space)
    uv = np.zeros((n_total, 2))
    uv[offset : offset + n] = desc[2]
    return TextureColors(desc[1], VertexUV(uv))


def add_trimesh(
    collection: Any,
    mesh_or_path: Any,
    material: Any = None,
    colors: Any = None,
    merge: bool = True,
    smooth: bool = False,
    point_size: float = 0.01,
    **kwargs: Any,
) -> Any:
    """See :meth:`RenderablesCollection.add_trimesh`. ``material``/``colors`` override what the file says.
    A multi-object scene becomes one mesh with per-face materials (``merge=True``) or one mesh per object."""
    import trimesh

    merge, smooth = as_bool("merge", merge), as_bool("smooth", smooth)
    obj = load_trimesh(mesh_or_path) if isinstance(mesh_or_path, (str, os.PathLike)) else mesh_or_path
    # glTF stores vertex colours and colour factors linear (the spec); other formats sRGB-encoded
    gltf = isinstance(mesh_or_path, (str, os.PathLike)) and Path(mesh_or_path).suffix.lower() in (".glb", ".gltf")
    space = kwargs.pop("_color_space", "linear" if gltf else "srgb")
    if gltf and isinstance(obj, trimesh.Scene):
        _undo_blendify_y_up(obj)
    if isinstance(obj, trimesh.PointCloud):
        pts = np.asarray(obj.vertices, dtype=np.float64)
        if colors is None:
            c = getattr(obj, "colors", None)
            colors = (
                VertexColors(np.asarray(c)[:, :3], color_space=space)
                if c is not None and len(c) == len(pts)
                else UniformColors(_DEFAULT_COLOR)
            )
        return collection.add_pointcloud(
            pts, material or PrincipledBSDFMaterial(), colors, point_size=point_size, **kwargs
        )
    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in _dump(obj) if isinstance(g, (trimesh.Trimesh, trimesh.PointCloud))]
        if not geoms:
            raise InvalidSceneError("mesh_or_path: the trimesh scene holds no mesh or point cloud")
        meshes = [g for g in geoms if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        clouds = [g for g in geoms if isinstance(g, trimesh.PointCloud)]
        # the parts added one by one share the pose (and the tag, when there is only one part)
        single = len(clouds) + (len(meshes) if not merge else min(len(meshes), 1)) == 1
        shared = {k: v for k, v in kwargs.items() if single or k in ("rotation_mode", "rotation", "translation")}
        out = []
        for c in clouds:
            own = _tagged(collection, c, shared)
            out.append(add_trimesh(collection, c, material, colors, point_size=point_size, _color_space=space, **own))
        if not meshes:
            return out[0] if len(out) == 1 else out
        if not merge:
            for m in meshes:
                own = _tagged(collection, m, shared)
                out.append(add_trimesh(collection, m, material, colors, smooth=smooth, _color_space=space, **own))
            return out
        parts = [_part(m) for m in meshes]
        mats = [material or _material_of(m.visual) for m in meshes]
        if len(meshes) == 1:
            kwargs = _tagged(collection, meshes[0], kwargs)
    elif isinstance(obj, trimesh.Trimesh):
        if len(obj.faces) == 0:
            raise InvalidSceneError("mesh_or_path: the mesh has no faces (use a trimesh.PointCloud for points)")
        parts = [_part(obj)]
        mats = [material or _material_of(obj.visual)]
    else:
        raise InvalidSceneError(
            f"mesh_or_path: expected a trimesh.Trimesh, trimesh.Scene, trimesh.PointCloud or a "
            f"file path, got {_describe(obj)}"
        )
    sizes = [len(p[0]) for p in parts]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)
    n_total = int(sum(sizes))
    vertices = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + o for p, o in zip(parts, offsets)])
    if colors is not None:
        cols: list[Colors] = [colors] * len(parts) if not isinstance(colors, (list, tuple)) else list(colors)
    else:
        cols = [_colors(p[2], n_total, o, s, space) for p, o, s in zip(parts, offsets, sizes)]
    if len(parts) == 1:
        result = collection.add_mesh(vertices, faces, mats[0], cols[0], smooth=smooth, **kwargs)
    else:
        faces_material = np.concatenate([np.full(len(p[1]), i) for i, p in enumerate(parts)])
        result = collection.add_mesh(
            vertices, faces, mats, cols, faces_material=faces_material, smooth=smooth, **kwargs
        )
    return result
