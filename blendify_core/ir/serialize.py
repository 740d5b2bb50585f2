"""The IR as a JSON-able header plus named arrays (what scene files store and fingerprints hash).

:func:`scene_to_header` and :func:`scene_from_header` are exact inverses for every IR feature;
:mod:`blendify_core.io.scenefile` stores the pair in one ``.npz`` file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.io.scenefile import content_digest, read_scene_file, write_scene_file
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import camera_from_dict
from blendify_core.ir.colors import FacesUV, FileTextureColors, TextureColors, UniformColors, VertexColors, VertexUV
from blendify_core.ir.lights import BackgroundLight, EnvironmentMap, Light
from blendify_core.ir.materials import Material
from blendify_core.ir.params import decode_params
from blendify_core.ir.renderables import PARAMETRIC, PRIMITIVES
from blendify_core.ir.types import LIGHT_TYPES, MATERIAL_TYPES
from blendify_core.typing import AnyArray

__all__ = [
    "scene_to_header",
    "scene_from_header",
    "save_scene",
    "load_scene",
    "fingerprint",
    "material_from_dict",
    "light_from_dict",
    "background_from_dict",
    "environment_from_dict",
]

_LIGHTS: tuple[Any, ...] = LIGHT_TYPES
_MATERIAL_CLASSES: dict[str, Any] = {cls.__name__: cls for cls in MATERIAL_TYPES}
_LIGHT_CLASSES: dict[str, Any] = {cls.kind: cls for cls in _LIGHTS}


def scene_to_header(scene: Any, arrays: dict[str, AnyArray]) -> dict[str, Any]:
    """The JSON-able description of ``scene``; its arrays are added to ``arrays``."""
    cam = scene.camera
    return {
        "camera": None if cam is None else cam.to_dict(),
        "renderables": [r.to_dict(arrays, f"r{i}.") for i, r in enumerate(scene.renderables)],
        "lights": [light.to_dict() for light in scene.lights],
        "background": None if scene.lights.background is None else scene.lights.background.to_dict(),
        "environment": None if scene.lights.environment is None else scene.lights.environment.to_dict(arrays),
        # files attached for a backend (e.g. .blend for Cycles): part of the picture, so of the file and fingerprint
        "attachments": [
            {
                "format": a.format,
                "path": str(a.path),
                **({"approximations": list(a.approximations)} if a.approximations else {}),
            }
            for a in scene.attachments
        ],
    }


def save_scene(scene: Any, path: str | os.PathLike[str], relative_paths: bool = True) -> None:
    """Write ``scene`` to a portable ``.npz`` scene file, atomically."""

    def build() -> tuple[dict[str, Any], dict[str, AnyArray]]:
        arrays: dict[str, AnyArray] = {}
        return scene_to_header(scene, arrays), arrays

    write_scene_file(path, build, relative_paths=relative_paths)


def load_scene(scene: Any, path: str | os.PathLike[str], allow_outside: bool = False) -> Any:
    """Fill the empty ``scene`` from a scene file; every failure is an InvalidSceneError naming the file."""
    header, arrays = read_scene_file(path, allow_outside=allow_outside)
    try:
        with arrays:
            return scene_from_header(scene, header, arrays)
    except InvalidSceneError as exc:
        raise InvalidSceneError(f"path: {str(path)!r} holds an invalid scene: {exc}") from None
    except (KeyError, TypeError, IndexError, AttributeError, ValueError) as exc:
        raise InvalidSceneError(f"path: {str(path)!r} is corrupt ({type(exc).__name__}: {exc})") from None


def fingerprint(scene: Any) -> str:
    """SHA-256 over the canonical header and every array's dtype, shape and bytes (file textures by
    content), so the same scene hashes the same across processes and any change changes the hash."""
    arrays: dict[str, AnyArray] = {}
    return content_digest(scene_to_header(scene, arrays), arrays)


# -- materials and lights: each walks its class's parameter declaration (blendify_core.ir.params) ------


def material_from_dict(d: dict[str, Any], arrays: Mapping[str, AnyArray], base_dir: str | None = None) -> Material:
    """The material a scene file's ``{"kind", "color_space", "params"}`` describes (Material.to_dict)."""
    cls = _MATERIAL_CLASSES.get(d.get("kind", ""))
    if cls is None:
        raise InvalidSceneError(f"scene file: unknown material kind {d.get('kind')!r}")
    params = decode_params(f"scene file: {cls.__name__}", cls._params, d["params"], arrays, base_dir)
    defaults = {p.name: p.default for p in cls._params}
    fixed = {k: v for k, v in params.items() if k in cls._fixed_params}
    if not all(_json_equal(v, defaults[k]) for k, v in fixed.items()):
        # written before the preset's fixed parameters were refused: the same picture as its base class
        cls = cls.__mro__[1]
    else:
        params = {k: v for k, v in params.items() if k not in fixed}
    material: Material = cls(color_space=d["color_space"], **params)
    return material


def _json_equal(a: Any, b: Any) -> bool:
    return (list(a) if isinstance(a, (tuple, list)) else a) == (list(b) if isinstance(b, (tuple, list)) else b)


def light_from_dict(d: dict[str, Any], arrays: Mapping[str, AnyArray] | None = None) -> Light:
    """The light a scene file's ``{"kind", "tag", "params", "quaternion", "translation"}`` describes."""
    cls = _LIGHT_CLASSES.get(d.get("kind", ""))
    if cls is None:
        raise InvalidSceneError(f"scene file: unknown light kind {d.get('kind')!r}")
    params = decode_params(f"scene file: {cls.__name__}", cls._stored, d["params"], arrays or {})
    light: Light = cls(**params, rotation=d["quaternion"], translation=d["translation"])
    light._tag = d["tag"]
    return light


def background_from_dict(d: dict[str, Any]) -> dict[str, Any]:
    """``set_background_light`` keywords from a scene file's background entry."""
    return decode_params("scene file: BackgroundLight", BackgroundLight._stored, d, {})


def environment_from_dict(d: dict[str, Any], arrays: Mapping[str, AnyArray]) -> dict[str, Any]:
    """``set_environment_map`` keywords from a scene file's environment entry (its parameters, the image
    or path and the rotation)."""
    names = {p.name for p in EnvironmentMap._stored}
    params = decode_params("scene file: EnvironmentMap", EnvironmentMap._stored, {k: d[k] for k in names & set(d)}, {})
    src = arrays[d["image"]] if d.get("image") else d["path"]
    return {"image_or_path": src, "rotation": d["quaternion"], **params}


def _colors_from_dict(d: dict[str, Any], arrays: Mapping[str, AnyArray]) -> Any:
    def uv(u: dict[str, Any] | None) -> Any:
        if u is None:
            return None
        return (VertexUV if u["kind"] == "vertex_uv" else FacesUV)(arrays[u["data"]])

    kind = d["kind"]
    if kind == "uniform":
        return UniformColors(d["color"], color_space=d["color_space"])
    if kind == "vertex":
        return VertexColors(arrays[d["vertex_colors"]], color_space=d["color_space"])
    if kind == "texture":
        return TextureColors(
            arrays[d["texture"]], uv(d["uv_map"]), color_space=d["color_space"], interpolation=d["interpolation"]
        )
    if kind == "file_texture":
        return FileTextureColors(
            d["texture_path"], uv(d["uv_map"]), color_space=d["color_space"], interpolation=d["interpolation"]
        )
    raise InvalidSceneError(f"unknown colour kind {kind!r}")


def _polygons(arrays: Mapping[str, AnyArray], d: dict[str, Any]) -> Any:
    tris = arrays[d["faces"]]
    poly = arrays[d["faces"].replace("faces", "face_polygon")]
    corner = arrays[d["faces"].replace("faces", "face_corner")]
    m, k = d["n_polygons"], d["polygon_size"]
    # declared sizes are checked against the arrays before anything is allocated: a polygon has at least one
    # triangle and a k-gon k - 2 of them (a crafted header declaring 1e11 polygons asked for 2 TiB)
    if not isinstance(m, int) or isinstance(m, bool) or not 0 <= m <= len(tris):
        raise InvalidSceneError(f"n_polygons: the header declares {m!r} polygons for {len(tris)} triangles")
    if k is not None and (not isinstance(k, int) or isinstance(k, bool) or (m and not 1 <= k <= len(tris) + 2)):
        raise InvalidSceneError(f"polygon_size: the header declares {k!r} for {len(tris)} triangles")
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


def scene_from_header(scene: Any, h: dict[str, Any], arrays: Mapping[str, AnyArray]) -> Any:
    """Fill the empty ``scene`` from a header and its arrays (as :func:`scene_to_header` wrote them)."""

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
        elif kind in PRIMITIVES:
            params = dict(d["params"])
            adder = getattr(coll, f"add_{kind}_mesh")
            obj = adder(material=material, colors=colors, faces_material=d["faces_material"], **params, **pose)
            obj.set_smooth(bool(d.get("smooth", False)))
        elif kind in PARAMETRIC:
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
        light = light_from_dict(d, arrays)
        scene.lights._add(light, d["tag"])
    if h["background"] is not None:
        scene.lights.set_background_light(**background_from_dict(h["background"]))
    scene.attachments = [
        Attachment(d["format"], str(d["path"]), tuple(str(n) for n in d.get("approximations", ())))
        for d in h.get("attachments", [])
    ] + [
        Attachment("blend", str(d["path"]))
        for d in h.get("attached_blends", [])  # files of 0.1.0
    ]
    env = h["environment"]
    if env is not None:
        scene.lights.set_environment_map(**environment_from_dict(env, arrays))
    return scene
