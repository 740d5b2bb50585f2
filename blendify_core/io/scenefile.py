"""Portable scene files: one ``.npz`` holding a versioned JSON header and the arrays (no pickle)."""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core._memo import digest_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.validate import as_path

FORMAT = "blendify-core-scene"
VERSION = 1
_HEADER = "__header__"


def _rel(path: str, base: Path, relative: bool) -> str:
    if not relative:
        return path
    try:
        return os.path.relpath(path, base)
    except ValueError:  # another drive on Windows
        return path


def _scene_dict(scene: Any, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    cam = scene.camera
    return {
        "format": FORMAT,
        "version": VERSION,
        "camera": None if cam is None else cam.to_dict(),
        "renderables": [r.to_dict(arrays, f"r{i}.") for i, r in enumerate(scene.renderables)],
        "lights": [light.to_dict() for light in scene.lights],
        "background": None if scene.lights.background is None else scene.lights.background.to_dict(),
        "environment": None if scene.lights.environment is None else scene.lights.environment.to_dict(arrays),
        # .blend files attached for the Cycles backend: part of the picture, so of the file and the fingerprint
        "attached_blends": [{"path": str(p)} for p in getattr(scene, "attached_blends", [])],
    }


def _walk_paths(obj: Any, fn: Any) -> Any:
    """Apply ``fn`` to every file path in a header (keys 'texture_path' and 'path')."""
    if isinstance(obj, dict):
        return {
            k: (fn(v) if k in ("texture_path", "path") and isinstance(v, str) else _walk_paths(v, fn))
            for k, v in obj.items()
        }
    if isinstance(obj, list):
        return [_walk_paths(v, fn) for v in obj]
    return obj


def save_scene(scene: Any, path: str | os.PathLike[str], relative_paths: bool = True) -> None:
    from blendify_core._output import AtomicOutput

    p = as_path("path", path)
    if p.suffix.lower() != ".npz":
        raise InvalidSceneError(f"path: scene files end in .npz, got {str(path)!r}")
    # the destination is checked (folder, name, permissions) before the scene is serialised
    out = AtomicOutput(p, arg="path")
    try:
        arrays: dict[str, np.ndarray] = {}
        header = _scene_dict(scene, arrays)
        base = p.resolve().parent
        header = _walk_paths(header, lambda v: _rel(v, base, relative_paths))
        payload = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
        payload[_HEADER] = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    except BaseException:
        out.discard()
        raise
    with out, open(out.tmp, "wb") as f:
        np.savez_compressed(f, **payload)


def load_scene(path: str | os.PathLike[str], allow_outside: bool = False) -> Any:
    p = as_path("path", path)
    if not p.is_file():
        raise InvalidSceneError(f"path: no such scene file {str(path)!r}")
    try:
        loaded = np.load(p, allow_pickle=False)
        if not hasattr(loaded, "files"):  # a plain .npy array under an .npz name
            raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file (a single .npy array)")
        with loaded as data:
            if _HEADER not in data.files:
                raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file (no header)")
            header = json.loads(bytes(data[_HEADER]).decode("utf-8"))
            arrays = {k: data[k] for k in data.files if k != _HEADER}
    except InvalidSceneError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InvalidSceneError(
            f"path: {str(path)!r} is not a readable scene file ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise InvalidSceneError(f"path: {str(path)!r} is not a blendify-core scene file")
    version = header.get("version")
    if version != VERSION:
        raise InvalidSceneError(
            f"path: {str(path)!r} has scene format version {version!r}; this blendify-core reads version {VERSION}"
        )
    base = p.resolve().parent

    def resolve(v: str) -> str:
        full = (base / v).resolve() if not os.path.isabs(v) else Path(v).resolve()
        if not allow_outside and base not in full.parents and full != base:
            raise InvalidSceneError(
                f"path: the scene references {v!r}, outside the scene's folder {str(base)!r}; "
                "pass allow_outside=True to read it"
            )
        return str(full)

    header = _walk_paths(header, resolve)
    try:
        return _build(header, arrays)
    except InvalidSceneError as exc:
        raise InvalidSceneError(f"path: {str(path)!r} holds an invalid scene: {exc}") from None
    except (KeyError, TypeError, IndexError, AttributeError, ValueError) as exc:
        raise InvalidSceneError(f"path: {str(path)!r} is corrupt ({type(exc).__name__}: {exc})") from None


def _colors_from_dict(d: dict[str, Any], arrays: dict[str, np.ndarray]) -> Any:
    from blendify_core.ir import colors as c

    def uv(u: dict[str, Any] | None) -> Any:
        if u is None:
            return None
        return (c.VertexUV if u["kind"] == "vertex_uv" else c.FacesUV)(arrays[u["data"]])

    kind = d["kind"]
    if kind == "uniform":
        return c.UniformColors(d["color"], color_space=d["color_space"])
    if kind == "vertex":
        return c.VertexColors(arrays[d["vertex_colors"]], color_space=d["color_space"])
    if kind == "texture":
        return c.TextureColors(
            arrays[d["texture"]], uv(d["uv_map"]), color_space=d["color_space"], interpolation=d["interpolation"]
        )
    if kind == "file_texture":
        return c.FileTextureColors(
            d["texture_path"], uv(d["uv_map"]), color_space=d["color_space"], interpolation=d["interpolation"]
        )
    raise InvalidSceneError(f"unknown colour kind {kind!r}")


def _polygons(arrays: dict[str, np.ndarray], d: dict[str, Any]) -> Any:
    tris = arrays[d["faces"]]
    poly = arrays[d["faces"].replace("faces", "face_polygon")]
    corner = arrays[d["faces"].replace("faces", "face_corner")]
    m, k = d["n_polygons"], d["polygon_size"]
    if k is not None:
        out = np.zeros((m, k), dtype=np.int64)
        out[poly[:, None], corner] = tris
        return out
    sizes = np.zeros(m, dtype=np.int64)
    np.maximum.at(sizes, poly, corner.max(axis=1) + 1)
    polys = [np.zeros(s, dtype=np.int64) for s in sizes]
    for t, pi, cr in zip(tris, poly, corner):
        polys[pi][cr] = t
    return polys


def _build(h: dict[str, Any], arrays: dict[str, np.ndarray]) -> Any:
    from blendify_core.ir import renderables as rmod
    from blendify_core.ir.cameras import camera_from_dict
    from blendify_core.ir.colors import FacesUV, VertexUV
    from blendify_core.ir.lights import light_from_dict
    from blendify_core.ir.materials import material_from_dict
    from blendify_core.ir.scene import Scene

    scene = Scene()
    if h["camera"] is not None:
        scene.camera = camera_from_dict(h["camera"])
    coll = scene.renderables
    for d in h["renderables"]:
        mats = [material_from_dict(m, arrays, None) for m in d["materials"]]
        cols = [_colors_from_dict(c, arrays) for c in d["colors"]]
        material: Any = mats[0] if len(mats) == 1 else mats
        colors: Any = cols[0] if len(cols) == 1 else cols
        pose = {"rotation": d["quaternion"], "translation": d["translation"], "tag": d["tag"]}
        kind = d["kind"]
        if kind == "mesh":
            uvd = d["uv_map"]
            uv = None if uvd is None else (VertexUV if uvd["kind"] == "vertex_uv" else FacesUV)(arrays[uvd["data"]])
            fm = None if d["faces_material"] is None else arrays[d["faces_material"]]
            obj: Any = coll.add_mesh(
                arrays[d["vertices"]], _polygons(arrays, d), material, colors, fm, uv, d["smooth"], **pose
            )
        elif kind == "pointcloud":
            size = arrays[d["point_size"]] if isinstance(d["point_size"], str) else d["point_size"]
            obj = coll.add_pointcloud(
                arrays[d["vertices"]],
                material,
                colors,
                size,
                d["base_primitive"],
                d["particle_emission_strength"],
                **pose,
            )
        elif kind in rmod._PRIMITIVES:
            params = dict(d["params"])
            adder = getattr(coll, f"add_{kind}_mesh")
            obj = adder(material=material, colors=colors, faces_material=d["faces_material"], **params, **pose)
            if d.get("smooth"):
                obj.set_smooth(True)
        elif kind in rmod._PARAMETRIC:
            params = dict(d["params"])
            if kind == "curve":
                params["keypoints"] = arrays[params["keypoints"]]
                obj = coll.add_curve_nurbs(material=material, colors=colors, **params, **pose)
            else:
                obj = getattr(coll, f"add_{kind}_nurbs")(material=material, colors=colors, **params, **pose)
        else:
            raise InvalidSceneError(f"unknown renderable kind {kind!r}")
        obj.emit_shadows = d["emit_shadows"]
    for d in h["lights"]:
        light = light_from_dict(d)
        scene.lights._add(light, d["tag"])
    if h["background"] is not None:
        scene.lights.set_background_light(**h["background"])
    scene.attached_blends = [str(d["path"]) for d in h.get("attached_blends", [])]  # optional: older files
    env = h["environment"]
    if env is not None:
        src = arrays[env["image"]] if env.get("image") else env["path"]
        scene.lights.set_environment_map(
            src, env["strength"], rotation=env["quaternion"], color_space=env["color_space"]
        )
    return scene


_file_hash_cache: dict[tuple[str, float, int], str] = {}


def _file_digest(path: str) -> str:
    st = os.stat(path)
    key = (path, st.st_mtime, st.st_size)
    if key not in _file_hash_cache:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        _file_hash_cache[key] = h.hexdigest()
    return _file_hash_cache[key]


def fingerprint(scene: Any) -> str:
    """SHA-256 over the canonical header and every array's dtype, shape and bytes (file textures by
    content), so the same scene hashes the same across processes and any change changes the hash."""
    arrays: dict[str, np.ndarray] = {}
    header = _scene_dict(scene, arrays)
    header = _walk_paths(header, lambda v: "sha256:" + _file_digest(v) if os.path.isfile(v) else v)
    h = hashlib.sha256()
    h.update(json.dumps(header, sort_keys=True).encode("utf-8"))
    for key in sorted(arrays):
        a = arrays[key]
        h.update(f"{key}|{a.dtype.str}|{a.shape}|".encode())
        h.update(digest_memo(a, _array_digest).encode())
    return h.hexdigest()


def _array_digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()
