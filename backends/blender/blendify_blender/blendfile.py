""".blend files: attach (parse a .blend into the IR) and export (write an IR scene as a .blend).

:func:`attach_blend` reads a .blend WITHOUT opening it as Blender's main file: the file's scenes are
appended with ``bpy.data.libraries.load(path, link=False)`` into the running bpy session, parsed into
the numpy IR, and every datablock the load created is removed again before returning, so the bpy
session (and the Cycles backend's state) is left as it was.

Security: nothing embedded in the file is ever executed, whatever the user's Blender preferences say.

- ``preferences.filepaths.use_scripts_auto_execute`` is forced to False for the whole load and
  evaluation (and restored afterwards), see :func:`scripts_auto_execute_disabled`;
- text blocks are never requested from the library (a text block pulled in indirectly is removed
  before anything is evaluated; registered ``use_module`` texts only run on ``wm.open_mainfile``,
  which is never used);
- every driver with a Python expression (``type == 'SCRIPTED'`` and not a "simple expression", which
  Blender evaluates in C without Python) is deleted right after the load, BEFORE the first depsgraph
  evaluation: with auto-run off Blender would still run such expressions in its restricted namespace;
  the deleted drivers are listed in the warning.

What is parsed into the IR (``scene`` must be a :class:`blendify_core.ir.scene.Scene`):

- meshes and everything that converts to a mesh (curves, surfaces, text, metaballs, geometry-nodes
  output, collection and particle instances), evaluated through the depsgraph with the RENDER
  visibility and the render subdivision levels of their modifiers, triangulated, with the instance's
  world transform (scale and shear baked into the object-space vertices, rotation and translation kept
  as the pose); vertices are split where Blender's corner normals (sharp edges, flat faces) or corner
  colours differ, so smooth/flat shading is kept; ``visible_shadow`` -> ``emit_shadows``;
- native point clouds (e.g. Geometry Nodes Mesh to Points) -> :class:`~blendify_core.ir.renderables.PointCloud`
  (per-point radius and colour attribute, emission from the colour -> ``particle_emission_strength``);
- UV layers -> :class:`~blendify_core.ir.colors.FacesUV`; colour attributes read by the material (Color
  Attribute / Attribute node on the Base Color, any domain and storage) ->
  :class:`~blendify_core.ir.colors.VertexColors` (linear);
- image textures on a Principled Base Color -> :class:`~blendify_core.ir.colors.FileTextureColors`
  (external files, by absolute path; PACKED images are written to ``texture_dir`` if given, else to the
  cache directory ``$XDG_CACHE_HOME/blendify-core/blend-textures`` (``~/.cache/...``), named by the
  SHA-256 of their bytes, and never deleted by the library) or
  :class:`~blendify_core.ir.colors.TextureColors` (generated images: pixels read from Blender);
  texture-driven Roughness / Metallic -> ``roughness_map`` / ``metallic_map``, a tangent-space Normal
  Map node fed by an image -> ``normal_map``;
- Principled BSDF (and Diffuse / Glossy / Emission shaders, a Mix with a Transparent BSDF = alpha, a Mix
  with a Wireframe factor = wireframe material) -> PrincipledBSDFMaterial / GlossyBSDFMaterial /
  PrincipledBSDFWireframeMaterial with every mapped parameter (``color_space="linear"``); per-face
  materials;
- point, sun, spot and area lights of every shape (square, rectangle, disk, ellipse; object scale
  applied to the size) in the IR's units (exposure, ``normalize=False`` and temperature folded into
  strength and colour; Blender's point-light "soft falloff" is not represented: the IR light is the
  sphere light without it, as the Cycles translator renders it);
- the world: Background colour x strength -> background light, an Environment Texture (with a Mapping
  rotation) -> environment map, both when summed by an Add Shader; imported only when the scene has
  neither yet unless ``with_world=True``;
- with ``with_camera=True``: the scene camera (resolution and percentage, lens / sensor / sensor fit /
  pixel aspect -> K, the principal point from ``shift_x`` / ``shift_y`` with the correct sign -- blendify
  2.1 mirrored it --, clipping, orthographic cameras).

What cannot be parsed (procedural shader trees, volumes, hair curves, panoramic cameras, Python drivers,
depth of field, shadow catchers, ...) is listed in ONE :class:`BlendAttachWarning` (also in the result's
``unparsed``). The resolved file path is appended to ``scene.attached_blends``, so the Cycles backend
can append the raw file content again for Cycles-only rendering of those features, through
:func:`append_blend_scenes` (same protections; the caller owns and removes the new datablocks); the
other backends render the parsed IR.

:func:`export_blend` builds the bpy scene with the Cycles translator (the same translation the renders
use), packs the images into the file and writes it with ``bpy.data.libraries.write`` (no ``.blend1``
backup, the main file and the working directory are untouched). Objects carry their IR tag as the
custom property ``blendify_tag``, so an exported scene attaches back with the same tags.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError, RenderError
from blendify_core.ir.attachments import Attachment

__all__ = [
    "AttachedBlend",
    "BlendAttachWarning",
    "append_blend_scenes",
    "attach_blend",
    "blender_camera_intrinsics",
    "check_blend_path",
    "default_texture_cache_dir",
    "export_blend",
    "scripts_auto_execute_disabled",
]

# gzip (Blender < 3.0 compressed files) and zstd (Blender >= 3.0 compressed files) magic numbers
_BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")
_LINEAR_SPACES = ("linear", "non-color", "raw", "scene_linear", "xyz", "acescg", "aces2065")


class BlendAttachWarning(UserWarning):
    """Parts of a .blend file that could not be parsed into the IR (listed in the message)."""


class AttachedBlend(list):  # type: ignore[type-arg]
    """The renderables added by :func:`attach_blend` (a list), plus what else was imported.

    Attributes: ``path`` (resolved .blend path), ``lights`` (added lights), ``camera`` (the new camera or
    None), ``background`` (the new background light / environment or None), ``unparsed`` (the warning
    lines), ``texture_dir`` (where packed textures were unpacked, or None), ``scene_name``.
    """

    def __init__(self, renderables: list[Any]) -> None:
        super().__init__(renderables)
        self.path: str = ""
        self.scene_name: str = ""
        self.lights: list[Any] = []
        self.camera: Any = None
        self.background: Any = None
        self.unparsed: list[str] = []
        self.texture_dir: str | None = None


# ---------------------------------------------------------------------------------------------------
# safety helpers
# ---------------------------------------------------------------------------------------------------


def check_blend_path(path: Any, name: str = "path") -> Path:
    """Validate that ``path`` names an existing .blend file (by its header); returns the resolved path."""
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidSceneError(f"{name}: expected a path to a .blend file, got {type(path).__name__} {path!r}")
    p = Path(path).expanduser()
    if not p.exists():
        raise InvalidSceneError(f"{name}: no such file {str(p)!r}")
    if not p.is_file():
        raise InvalidSceneError(f"{name}: expected a .blend file, got a directory {str(p)!r}")
    try:
        with open(p, "rb") as fh:
            head = fh.read(8)
    except OSError as exc:
        raise InvalidSceneError(f"{name}: cannot read {str(p)!r} ({exc})") from None
    if not any(head.startswith(m) for m in _BLEND_MAGICS):
        raise InvalidSceneError(
            f"{name}: {str(p)!r} is not a .blend file (its header is {head[:7]!r}, expected b'BLENDER' or a "
            "compressed .blend)"
        )
    return p.resolve()


def _bpy() -> Any:
    from . import _runtime

    return _runtime.bpy_module()


@contextlib.contextmanager
def scripts_auto_execute_disabled() -> Iterator[None]:
    """Force Blender's "Auto Run Python Scripts" preference off inside the block, restore it afterwards."""
    bpy = _bpy()
    prefs = bpy.context.preferences.filepaths
    old = bool(prefs.use_scripts_auto_execute)
    prefs.use_scripts_auto_execute = False
    try:
        yield
    finally:
        prefs.use_scripts_auto_execute = old


def _id_collections(bpy: Any) -> list[Any]:
    """Every ``bpy.data`` collection holding IDs (found through RNA, so new Blender versions are covered)."""
    out = []
    for prop in bpy.data.bl_rna.properties:
        if prop.type != "COLLECTION" or prop.identifier in ("window_managers", "screens", "workspaces"):
            continue
        base = getattr(prop, "fixed_type", None)
        while base is not None and base.identifier != "ID":
            base = base.base
        if base is not None:
            out.append(getattr(bpy.data, prop.identifier))
    return out


def _all_ids(bpy: Any) -> dict[int, Any]:
    ids: dict[int, Any] = {}
    for coll in _id_collections(bpy):
        for idb in coll:
            ids[idb.as_pointer()] = idb
    return ids


def _python_drivers(idb: Any) -> Iterator[tuple[Any, Any, Any]]:
    """(owner, animation_data, fcurve) for every driver of ``idb`` (and its embedded node tree / shape
    keys) whose expression needs Python."""
    owners = [idb]
    for attr in ("node_tree", "shape_keys"):
        sub = getattr(idb, attr, None)
        if sub is not None and hasattr(sub, "animation_data"):
            owners.append(sub)
    for owner in owners:
        ad = getattr(owner, "animation_data", None)
        if ad is None:
            continue
        for fc in list(ad.drivers):
            drv = fc.driver
            if drv.type == "SCRIPTED" and not drv.is_simple_expression:
                yield owner, ad, fc


def _strip_python(bpy: Any, new_ids: list[Any]) -> list[str]:
    """Remove Python drivers and text blocks among freshly loaded IDs; returns what was removed."""
    removed: list[str] = []
    texts = [i for i in new_ids if isinstance(i, bpy.types.Text)]
    for idb in new_ids:
        if isinstance(idb, bpy.types.Text):
            continue
        for owner, ad, fc in list(_python_drivers(idb)):
            what = f"Python driver on {owner.name!r} {fc.data_path}[{fc.array_index}] = {fc.driver.expression!r}"
            try:
                ad.drivers.remove(fc)
            except (RuntimeError, TypeError, AttributeError, ReferenceError) as exc:
                # e.g. data linked from another library is read-only: refuse rather than evaluate it
                raise InvalidSceneError(
                    f"path: the file contains a {what} that cannot be removed ({exc}); refusing to evaluate it"
                ) from None
            removed.append(f"{what} (removed, never evaluated)")
    for t in texts:
        removed.append(f"text block {t.name!r} (removed, never run)")
    if texts:
        bpy.data.batch_remove(texts)
    return removed


@contextlib.contextmanager
def _loaded_blend(path: Path) -> Iterator[tuple[list[tuple[str, Any]], list[str], list[Any]]]:
    """Append all scenes of ``path`` safely; yields ((name in the file, scene) sorted by name,
    removed-Python notes, all new IDs); removes every new ID on exit. Auto-run must already be forced
    off by the caller."""
    bpy = _bpy()
    before = set(_all_ids(bpy))
    renamed: list[tuple[Any, str]] = []
    try:
        try:
            with bpy.data.libraries.load(str(path), link=False) as (src, dst):
                src_names = list(src.scenes)
                dst.scenes = list(src_names)
                # session objects whose names the file uses are renamed for the duration, so the
                # appended objects keep their own names (they become the IR tags)
                for i, nm in enumerate(src.objects):
                    existing = bpy.data.objects.get(nm)
                    if existing is not None and existing.library is None:
                        renamed.append((existing, nm))
                        existing.name = f"~bf{i}~{nm}"[:60]
        except (OSError, RuntimeError, ValueError) as exc:
            raise InvalidSceneError(f"path: Blender cannot read {str(path)!r} as a .blend file ({exc})") from None
        removed = _strip_python(bpy, [idb for ptr, idb in _all_ids(bpy).items() if ptr not in before])
        # (name in the file, appended scene): appended scenes are renamed when the session has the name
        scenes = sorted(((n, sc) for n, sc in zip(src_names, dst.scenes) if sc is not None), key=lambda x: x[0])
        if not scenes:
            raise InvalidSceneError(f"path: {str(path)!r} contains no scene")
        new_ids = [idb for ptr, idb in _all_ids(bpy).items() if ptr not in before]
        yield scenes, removed, new_ids
    finally:
        leftover = [i for ptr, i in _all_ids(bpy).items() if ptr not in before]
        if leftover:
            bpy.data.batch_remove(leftover)
        for obj, nm in renamed:
            obj.name = nm


def append_blend_scenes(path: str | os.PathLike[str]) -> tuple[list[Any], list[str]]:
    """For the Cycles backend: append the scenes of ``path`` into the current bpy session with the same
    protections as :func:`attach_blend` (auto-run off during the load, Python drivers and text blocks
    removed). Returns (appended bpy scenes, notes about removed Python). The caller owns the new
    datablocks and must keep auto-run off while evaluating them (drivers are already gone)."""
    from . import _runtime

    bpy = _bpy()
    p = check_blend_path(path)
    with _runtime.BPY_LOCK, scripts_auto_execute_disabled():
        before = set(_all_ids(bpy))
        try:
            with bpy.data.libraries.load(str(p), link=False) as (src, dst):
                dst.scenes = list(src.scenes)
        except (OSError, RuntimeError, ValueError) as exc:
            raise InvalidSceneError(f"path: Blender cannot read {str(p)!r} as a .blend file ({exc})") from None
        try:
            removed = _strip_python(bpy, [idb for ptr, idb in _all_ids(bpy).items() if ptr not in before])
        except BaseException:
            bpy.data.batch_remove([i for ptr, i in _all_ids(bpy).items() if ptr not in before])
            raise
    return [s for s in dst.scenes if s is not None], removed


# ---------------------------------------------------------------------------------------------------
# small numeric helpers
# ---------------------------------------------------------------------------------------------------


def _mat(m: Any) -> np.ndarray:
    return np.array([list(row) for row in m], dtype=np.float64)


def _decompose(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """4x4 -> (R proper rotation, S = R^T A (scale/shear, may contain a reflection), t)."""
    a = m[:3, :3]
    u, _s, vt = np.linalg.svd(a)
    r = u @ vt
    if np.linalg.det(r) < 0:
        r = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    s = r.T @ a
    return r, s, m[:3, 3].copy()


def _rotation_only(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r, _s, t = _decompose(m)
    return r, t


def _is_identity(s: np.ndarray, tol: float = 1e-7) -> bool:
    return bool(np.max(np.abs(s - np.eye(3))) <= tol)


def _rgb01(rgb: Any) -> tuple[np.ndarray, float]:
    """Split a linear RGB (may exceed 1; negative values are clipped) into a [0, 1] colour and a
    multiplier (the IR keeps colours in [0, 1] and intensities in strengths)."""
    c = np.clip(np.asarray(rgb, dtype=np.float64)[:3], 0.0, None)
    peak = float(c.max()) if c.size else 0.0
    if peak > 1.0:
        return c / peak, peak
    return c, 1.0


def default_texture_cache_dir() -> Path:
    """Where packed textures are unpacked when ``texture_dir`` is not given."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "blendify-core" / "blend-textures"


# ---------------------------------------------------------------------------------------------------
# camera
# ---------------------------------------------------------------------------------------------------


def blender_camera_intrinsics(
    cam: Any, width: int, height: int, pixel_aspect_x: float = 1.0, pixel_aspect_y: float = 1.0
) -> dict[str, Any]:
    """OpenCV intrinsics of a Blender camera datablock at ``width`` x ``height`` pixels.

    Follows Blender's view-plane computation: the fitted sensor dimension spans ``viewfac`` pixels
    (``W`` for horizontal fit, ``H * ycor`` for vertical, ``ycor = pixel_aspect_y / pixel_aspect_x``),
    ``shift`` is in units of ``viewfac`` and +shift_y moves the view UP. Pixel centres are at integers:
    ``cx = W/2 - shift_x * viewfac - 0.5``, ``cy = H/2 + shift_y * viewfac / ycor - 0.5``,
    ``fx = lens * viewfac / sensor``, ``fy = fx / ycor``. Orthographic: ``ortho_scale`` (IR: visible
    width) = Blender ortho_scale * W / viewfac. Returns a dict with fx, fy, cx, cy, ortho_scale, type.
    """
    w, h = float(width), float(height)
    ycor = float(pixel_aspect_y) / float(pixel_aspect_x)
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if pixel_aspect_x * w >= pixel_aspect_y * h else "VERTICAL"
        sensor = cam.sensor_width
    elif fit == "HORIZONTAL":
        sensor = cam.sensor_width
    else:
        sensor = cam.sensor_height
    viewfac = w if fit == "HORIZONTAL" else ycor * h
    cx = w / 2.0 - cam.shift_x * viewfac - 0.5
    cy = h / 2.0 + cam.shift_y * viewfac / ycor - 0.5
    out: dict[str, Any] = {"type": cam.type, "cx": cx, "cy": cy, "ycor": ycor}
    if cam.type == "ORTHO":
        out["ortho_scale"] = cam.ortho_scale * w / viewfac
    else:
        fx = cam.lens * viewfac / sensor
        out["fx"] = fx
        out["fy"] = fx / ycor
    return out


# ---------------------------------------------------------------------------------------------------
# the parser
# ---------------------------------------------------------------------------------------------------


@dataclass
class _Pending:
    """Everything parsed from the file, committed to the IR scene only when parsing succeeded."""

    meshes: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    points: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    lights: list[tuple[str, str, dict[str, Any]]] = field(default_factory=list)
    camera: tuple[str, dict[str, Any]] | None = None
    world: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


_FLOAT_INPUTS = {
    "Metallic": "metallic",
    "Roughness": "roughness",
    "IOR": "ior",
    "Alpha": "alpha",
    "Diffuse Roughness": "diffuse_roughness",
    "Subsurface Weight": "subsurface_weight",
    "Subsurface Scale": "subsurface_scale",
    "Subsurface Anisotropy": "subsurface_anisotropy",
    "Specular IOR Level": "specular_ior",
    "Anisotropic": "anisotropic",
    "Anisotropic Rotation": "anisotropic_rotation",
    "Transmission Weight": "transmission_weight",
    "Coat Weight": "coat_weight",
    "Coat Roughness": "coat_roughness",
    "Coat IOR": "coat_ior",
    "Sheen Weight": "sheen_weight",
    "Sheen Roughness": "sheen_roughness",
    "Emission Strength": "emission_strength",
    "Thin Film Thickness": "thin_film_thickness",
    "Thin Film IOR": "thin_film_ior",
}
_COLOR_INPUTS = {
    "Specular Tint": "specular_tint",
    "Coat Tint": "coat_tint",
    "Sheen Tint": "sheen_tint",
    "Emission Color": "emission_color",
}
_IGNORED_INPUTS = ("Weight", "Tangent", "Coat Normal", "Subsurface IOR")

_IMAGE_EXT = {
    "PNG": ".png",
    "JPEG": ".jpg",
    "OPEN_EXR": ".exr",
    "OPEN_EXR_MULTILAYER": ".exr",
    "TARGA": ".tga",
    "TARGA_RAW": ".tga",
    "BMP": ".bmp",
    "TIFF": ".tif",
    "HDR": ".hdr",
    "WEBP": ".webp",
}


def _param_ranges() -> dict[str, tuple[float | None, float | None]]:
    from blendify_core.ir.materials import PrincipledBSDFMaterial

    return {p.name: (p.min_value, p.max_value) for p in PrincipledBSDFMaterial._params if p.kind == "float"}


class _Parser:
    def __init__(self, bpy: Any, blend_path: Path, texture_dir: str | os.PathLike[str] | None):
        self.bpy = bpy
        self.blend_path = blend_path
        self.texture_dir_arg = texture_dir
        self.texture_dir: Path | None = None
        self.notes: list[str] = []
        self._ranges = _param_ranges()
        self._image_cache: dict[int, Any] = {}
        self._material_cache: dict[tuple[int, int], Any] = {}

    def note(self, msg: str) -> None:
        if msg not in self.notes:
            self.notes.append(msg)

    # -- images ----------------------------------------------------------------------------------
    def _unpack_dir(self) -> Path:
        if self.texture_dir is None:
            d = Path(self.texture_dir_arg).expanduser() if self.texture_dir_arg is not None else None
            d = d or default_texture_cache_dir()
            try:
                d.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise InvalidSceneError(f"texture_dir: cannot create {str(d)!r} ({exc})") from None
            self.texture_dir = d.resolve()
        return self.texture_dir

    def image_source(self, image: Any, where: str) -> tuple[str, Any, str] | None:
        """('file', path, color_space) or ('pixels', array row 0 = top, color_space), or None."""
        key = image.as_pointer()
        if key in self._image_cache:
            return self._image_cache[key]
        cs_name = image.colorspace_settings.name
        low = cs_name.lower()
        if low in ("srgb", "srgb 2.2", "srgb texture") or low.startswith("srgb"):
            cs = "srgb"
        elif any(low.startswith(x) for x in _LINEAR_SPACES):
            cs = "linear"
        else:
            cs = "srgb"
            self.note(f"{where}: image {image.name!r} colour space {cs_name!r} read as sRGB (approximation)")
        result: tuple[str, Any, str] | None = None
        if image.source == "TILED":
            self.note(f"{where}: UDIM image {image.name!r} not supported")
        elif image.source in ("MOVIE", "SEQUENCE", "VIEWER"):
            self.note(f"{where}: {image.source.lower()} image {image.name!r} not supported")
        elif image.packed_file is not None:
            data = bytes(image.packed_file.data)
            ext = Path(image.filepath_raw or image.filepath or "").suffix.lower() or _IMAGE_EXT.get(
                image.file_format, ".png"
            )
            digest = hashlib.sha256(data).hexdigest()[:24]
            target = self._unpack_dir() / f"{digest}{ext}"
            if not target.is_file():
                tmp = target.with_name(target.name + f".{os.getpid()}.tmp")
                tmp.write_bytes(data)
                os.replace(tmp, target)
            result = ("file", str(target), cs)
        else:
            fp = image.filepath_raw or image.filepath
            resolved = None
            if fp and image.source == "FILE":
                cand = self.bpy.path.abspath(fp, library=image.library)
                if fp.startswith("//"):
                    alt = self.blend_path.parent / fp[2:]
                    if alt.is_file():
                        cand = str(alt)
                if os.path.isfile(cand):
                    resolved = os.path.abspath(cand)
            if resolved is not None:
                result = ("file", resolved, cs)
            elif image.has_data or image.source == "GENERATED":
                w, h = image.size
                if w and h:
                    ch = image.channels
                    px = np.empty(w * h * ch, dtype=np.float32)
                    image.pixels.foreach_get(px)
                    arr = px.reshape(h, w, ch)[::-1]
                    if ch == 4 and np.all(arr[..., 3] >= 1.0):
                        arr = arr[..., :3]
                    # float buffers are scene-linear, byte buffers keep their colour space's encoding
                    cs_px = "linear" if image.is_float else cs
                    if float(arr.max(initial=0.0)) > 1.0:
                        self.note(f"{where}: image {image.name!r} has values > 1, clipped to [0, 1]")
                    arr = np.ascontiguousarray(np.clip(arr, 0.0, 1.0))
                    result = ("pixels", arr, cs_px)
            if result is None:
                self.note(f"{where}: image {image.name!r} file {fp!r} not found")
        self._image_cache[key] = result
        return result

    # -- node helpers ----------------------------------------------------------------------------
    @staticmethod
    def _link_from(socket: Any) -> tuple[Any, Any] | None:
        if not socket.is_linked:
            return None
        for link in socket.links:
            if link.is_valid and not link.is_muted:
                node = link.from_node
                # follow reroutes
                while node.type == "REROUTE" and node.inputs[0].is_linked:
                    link = node.inputs[0].links[0]
                    node = link.from_node
                if node.type == "REROUTE":
                    return None
                return node, link.from_socket
        return None

    def _uv_layer_name(self, image_node: Any, where: str) -> str | None:
        """'' = the mesh's render UV layer, a name, or None when the vector input is not a plain UV."""
        vec = image_node.inputs.get("Vector")
        if vec is None:
            return ""
        src = self._link_from(vec)
        if src is None:
            return ""
        node, sock = src
        if node.type == "UVMAP":
            return node.uv_map
        if node.type == "TEX_COORD" and sock.name == "UV":
            return ""
        self.note(f"{where}: texture coordinates from a {node.bl_idname} node replaced by the UV map")
        return ""

    def _texture_input(self, socket: Any, where: str, what: str) -> dict[str, Any] | None:
        """An Image Texture feeding ``socket``: {'image': source, 'uv': layer name, 'channel', ...}."""
        src = self._link_from(socket)
        if src is None:
            return None
        node, out = src
        if node.type != "TEX_IMAGE":
            self.note(
                f"{where}: {what} comes from a {node.bl_idname} node (procedural), used its default value instead"
            )
            return None
        if node.image is None:
            self.note(f"{where}: {what} image node has no image")
            return None
        if node.projection != "FLAT":
            self.note(f"{where}: {what} image projection {node.projection} read as FLAT")
        img = self.image_source(node.image, where)
        if img is None:
            return None
        return {
            "image": img,
            "uv": self._uv_layer_name(node, where),
            "channel": 3 if out.name == "Alpha" else 0,
            "interpolation": "closest" if node.interpolation == "Closest" else "linear",
        }

    def _color_source(self, socket: Any, where: str) -> dict[str, Any]:
        """How a colour input is driven: uniform value, a colour attribute or an image texture."""
        src = self._link_from(socket)
        default = tuple(socket.default_value)
        if src is None:
            return {"kind": "uniform", "rgba": default}
        node, out = src
        if node.type == "TEX_IMAGE":
            tex = self._texture_input(socket, where, socket.name)
            if tex is not None:
                return {"kind": "texture", "node": node, **tex}
        elif node.type == "VERTEX_COLOR":
            return {"kind": "attribute", "name": node.layer_name, "node": node}
        elif node.type == "ATTRIBUTE" and node.attribute_type == "GEOMETRY" and out.name == "Color":
            return {"kind": "attribute", "name": node.attribute_name, "node": node}
        elif node.type == "RGB":
            return {"kind": "uniform", "rgba": tuple(out.default_value)}
        else:
            self.note(f"{where}: {socket.name} comes from a {node.bl_idname} node (procedural), used its default value")
        return {"kind": "uniform", "rgba": default}

    # -- materials -------------------------------------------------------------------------------
    def material(self, mat: Any, where: str) -> tuple[Any, dict[str, Any]]:
        """(IR material, colour source description) of a Blender material (or None)."""
        from blendify_core.ir.materials import PrincipledBSDFMaterial

        if mat is None:
            return PrincipledBSDFMaterial(color_space="linear"), {"kind": "uniform", "rgba": (0.8, 0.8, 0.8, 1.0)}
        where = f"{where} material {mat.name!r}"
        tree = mat.node_tree
        fallback = {"kind": "uniform", "rgba": tuple(mat.diffuse_color)}
        if tree is None:
            return PrincipledBSDFMaterial(
                color_space="linear",
                metallic=float(mat.metallic),
                roughness=float(mat.roughness),
            ), fallback
        outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL" and n.target in ("ALL", "CYCLES")]
        active = [n for n in outputs if n.is_active_output] or outputs
        if not active:
            self.note(f"{where}: no Material Output node, rendered as default grey")
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        out = active[0]
        for extra in ("Volume", "Displacement", "Thickness"):
            sock = out.inputs.get(extra)
            if sock is not None and sock.is_linked:
                self.note(f"{where}: {extra.lower()} shader not parsed")
        src = self._link_from(out.inputs["Surface"])
        if src is None:
            self.note(f"{where}: nothing connected to the surface output, rendered as default grey")
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        parsed = self._shader(src[0], where)
        if parsed is None:
            self.note(
                f"{where}: surface shader {src[0].bl_idname} (node tree) cannot be parsed, "
                "rendered as a Principled BSDF with the viewport colour"
            )
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        return parsed

    def _shader(self, node: Any, where: str) -> tuple[Any, dict[str, Any]] | None:
        """(IR material, colour description) of a shader node, or None when it cannot be parsed."""
        from blendify_core.ir.materials import GlossyBSDFMaterial, PrincipledBSDFMaterial

        if node.type == "BSDF_PRINCIPLED":
            return self._principled(node, where)
        if node.type == "BSDF_DIFFUSE":
            col = self._color_source(node.inputs["Color"], where)
            self._ignore_links(node, ("Color",), where)
            return PrincipledBSDFMaterial(color_space="linear", roughness=1.0, specular_ior=0.0), col
        if node.type == "BSDF_GLOSSY":
            col = self._color_source(node.inputs["Color"], where)
            self._ignore_links(node, ("Color",), where)
            dist = (
                node.distribution
                if node.distribution in ("GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY", "MULTI_GGX")
                else "GGX"
            )
            rough = float(np.clip(node.inputs["Roughness"].default_value, 0.0, 1.0))
            return GlossyBSDFMaterial(roughness=rough, distribution=dist, color_space="linear"), col
        if node.type == "EMISSION":
            self._ignore_links(node, (), where)
            c, k = _rgb01(node.inputs["Color"].default_value)
            strength = float(node.inputs["Strength"].default_value) * k
            m = PrincipledBSDFMaterial(
                color_space="linear",
                emission_color=tuple(c) + (1.0,),
                emission_strength=max(strength, 0.0),
                specular_ior=0.0,
                roughness=1.0,
            )
            return m, {"kind": "uniform", "rgba": (0.0, 0.0, 0.0, 1.0)}
        if node.type == "MIX_SHADER":
            return self._mix_shader(node, where)
        return None

    def _mix_shader(self, node: Any, where: str) -> tuple[Any, dict[str, Any]] | None:
        """Two patterns: a wireframe overlay (Mix with a Wireframe factor of two Principled BSDFs) and
        transparency (Mix of a Transparent BSDF and a shader, the factor being the alpha)."""
        from blendify_core.ir.materials import PrincipledBSDFWireframeMaterial

        fac = node.inputs[0]
        a = self._link_from(node.inputs[1])
        b = self._link_from(node.inputs[2])
        if a is None or b is None:
            return None
        fsrc = self._link_from(fac)
        if fsrc is not None and fsrc[0].type == "WIREFRAME" and a[0].type == b[0].type == "BSDF_PRINCIPLED":
            wire = fsrc[0]
            if wire.use_pixel_size:
                self.note(f"{where}: wireframe size in pixels read as world units")
            base, col = self._principled(a[0], where)
            wsock = b[0].inputs["Base Color"]
            if wsock.is_linked:
                self.note(f"{where}: wireframe colour driven by nodes, used its default value")
            wc, _k = _rgb01(wsock.default_value)
            params = base.parameters()
            m = PrincipledBSDFWireframeMaterial(
                wireframe_thickness=max(float(wire.inputs["Size"].default_value), 0.0),
                wireframe_color=(float(wc[0]), float(wc[1]), float(wc[2]), 1.0),
                color_space="linear",
                **params,
            )
            return m, col
        if a[0].type == "BSDF_TRANSPARENT" or b[0].type == "BSDF_TRANSPARENT":
            other = b[0] if a[0].type == "BSDF_TRANSPARENT" else a[0]
            parsed = self._shader(other, where)
            if parsed is None:
                return None
            m, col = parsed
            if fsrc is None:
                f = float(np.clip(fac.default_value, 0.0, 1.0))
                alpha = f if a[0].type == "BSDF_TRANSPARENT" else 1.0 - f
            elif fsrc[1].name == "Alpha" and col.get("node") == fsrc[0] and a[0].type == "BSDF_TRANSPARENT":
                alpha = 1.0  # the colour source's own alpha
            else:
                self.note(f"{where}: transparency factor driven by nodes, read as opaque")
                alpha = 1.0
            if "alpha" in m.parameter_names():
                m = m.copy(alpha=float(m.alpha) * alpha)
            return m, col
        return None

    def _ignore_links(self, node: Any, handled: tuple[str, ...], where: str) -> None:
        for sock in node.inputs:
            if sock.name not in handled and sock.enabled and sock.is_linked:
                self.note(f"{where}: {node.name} input {sock.name!r} is driven by nodes, used its default value")

    def _clip(self, name: str, value: float, where: str) -> float:
        lo, hi = self._ranges.get(name, (None, None))
        v = float(value)
        if not math.isfinite(v):
            self.note(f"{where}: {name} = {v} replaced by 0")
            return 0.0
        c = v
        if lo is not None and c < lo:
            c = lo
        if hi is not None and c > hi:
            c = hi
        if c != v and abs(c - v) > 1e-6:
            self.note(f"{where}: {name} = {v:g} clipped to {c:g}")
        return c

    def _principled(self, node: Any, where: str) -> tuple[Any, dict[str, Any]]:
        from blendify_core.ir.colors import NormalMap, TextureMap
        from blendify_core.ir.materials import PrincipledBSDFMaterial

        params: dict[str, Any] = {}
        inputs = {s.name: s for s in node.inputs}
        for bl_name, ir_name in _FLOAT_INPUTS.items():
            sock = inputs.get(bl_name)
            if sock is None:
                continue
            if sock.is_linked and ir_name in ("roughness", "metallic"):
                tex = self._texture_input(sock, where, bl_name)
                if tex is not None:
                    params[f"{ir_name}_map"] = self._texture_map(tex, TextureMap)
            elif ir_name == "alpha" and sock.is_linked:
                alpha = self._alpha_value(node)
                if alpha is None:
                    self.note(f"{where}: Principled input 'Alpha' is driven by nodes, used its default value")
                else:
                    params["alpha"] = self._clip("alpha", alpha, where)
                    continue
            elif sock.is_linked:
                self.note(f"{where}: Principled input {bl_name!r} is driven by nodes, used its default value")
            params[ir_name] = self._clip(ir_name, sock.default_value, where)
        base_src = self._link_from(inputs["Base Color"])
        emission_from_color = 0.0
        for bl_name, ir_name in _COLOR_INPUTS.items():
            sock = inputs.get(bl_name)
            if sock is None:
                continue
            if ir_name == "emission_color" and sock.is_linked and base_src is not None:
                esrc = self._link_from(sock)
                if esrc is not None and esrc[0] == base_src[0] and esrc[1].name == base_src[1].name:
                    # the surface emits its own colour (point clouds' particle_emission_strength)
                    emission_from_color = float(params.get("emission_strength", 0.0))
                    params["emission_strength"] = 0.0
                    continue
            if sock.is_linked:
                self.note(f"{where}: Principled input {bl_name!r} is driven by nodes, used its default value")
            c, k = _rgb01(sock.default_value)
            if k > 1.0:
                if ir_name == "emission_color":
                    params["emission_strength"] = params.get("emission_strength", 0.0) * k
                else:
                    self.note(f"{where}: {bl_name} > 1 normalised to [0, 1]")
            params[ir_name] = (float(c[0]), float(c[1]), float(c[2]), 1.0)
        sock = inputs.get("Subsurface Radius")
        if sock is not None:
            params["subsurface_radius"] = tuple(max(float(x), 0.0) for x in sock.default_value)
        normal = inputs.get("Normal")
        if normal is not None and normal.is_linked:
            src = self._link_from(normal)
            nm = None
            if src is not None and src[0].type == "NORMAL_MAP":
                nnode = src[0]
                if nnode.space != "TANGENT":
                    self.note(f"{where}: {nnode.space.lower()}-space normal map not supported")
                else:
                    tex = self._texture_input(nnode.inputs["Color"], where, "Normal Map color")
                    if tex is not None:
                        nm = self._texture_map(tex, NormalMap, strength=float(nnode.inputs["Strength"].default_value))
            elif src is not None:
                self.note(f"{where}: Normal input from a {src[0].bl_idname} node not parsed")
            if nm is not None:
                params["normal_map"] = nm
        for name in _IGNORED_INPUTS:
            s = inputs.get(name)
            if s is not None and s.enabled and s.is_linked:
                self.note(f"{where}: Principled input {name!r} not parsed")
        colors = self._color_source(inputs["Base Color"], where)
        if emission_from_color > 0:
            colors["emission_from_color"] = emission_from_color
        if colors["kind"] in ("texture", "attribute") and self._alpha_value(node) is None:
            colors["opaque"] = True  # Blender ignores the colour source's alpha: the IR must too
        return PrincipledBSDFMaterial(color_space="linear", **params), colors

    def _alpha_value(self, node: Any) -> float | None:
        """Material alpha when Alpha is the colour source's own alpha (the Alpha output of the node that
        feeds Base Color), optionally multiplied by a constant (Math MULTIPLY); else None."""
        base = self._link_from(node.inputs["Base Color"])
        a = self._link_from(node.inputs["Alpha"])
        if base is None or a is None:
            return None

        def is_colour_alpha(src: tuple[Any, Any] | None) -> bool:
            return src is not None and src[0] == base[0] and src[1].name == "Alpha"

        if is_colour_alpha(a):
            return 1.0
        mnode = a[0]
        if mnode.type == "MATH" and mnode.operation == "MULTIPLY":
            i0, i1 = mnode.inputs[0], mnode.inputs[1]
            if is_colour_alpha(self._link_from(i1)) and not i0.is_linked:
                return float(i0.default_value)
            if is_colour_alpha(self._link_from(i0)) and not i1.is_linked:
                return float(i1.default_value)
        return None

    def _texture_map(self, tex: dict[str, Any], cls: Any, **kw: Any) -> Any:
        kind, data, _cs = tex["image"]
        if cls.__name__ == "NormalMap":
            return cls(data, **kw)
        return (
            cls(data, channel=tex["channel"])
            if kind == "file"
            else cls(data, channel=min(tex["channel"], data.shape[2] - 1))
        )

    # -- meshes ----------------------------------------------------------------------------------
    def mesh_instance(self, bpy_obj: Any, matrix: np.ndarray, name: str, pend: _Pending) -> None:
        """Parse one evaluated object instance (anything convertible to a mesh)."""
        try:
            me = bpy_obj.to_mesh()
        except RuntimeError as exc:
            self.note(f"object {name!r}: cannot convert to a mesh ({exc})")
            return
        if me is None:
            return
        try:
            spec = self._mesh_spec(bpy_obj, me, matrix, name)
        finally:
            bpy_obj.to_mesh_clear()
        if spec is not None:
            pend.meshes.append((name, spec))

    def _mesh_spec(self, bpy_obj: Any, me: Any, matrix: np.ndarray, name: str) -> dict[str, Any] | None:
        from blendify_core.ir.colors import FacesUV, FileTextureColors, TextureColors, UniformColors, VertexColors

        me.calc_loop_triangles()
        nv, nt = len(me.vertices), len(me.loop_triangles)
        if nv == 0 or nt == 0:
            if nv:
                self.note(f"object {name!r}: {nv} vertices without faces (edges/points) skipped")
            return None
        co = np.empty(nv * 3, dtype=np.float32)
        me.vertices.foreach_get("co", co)
        verts = co.reshape(nv, 3).astype(np.float64)
        tv = np.empty(nt * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("vertices", tv)
        tris = tv.reshape(nt, 3)
        tl = np.empty(nt * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("loops", tl)
        tri_loops = tl.reshape(nt, 3)
        tp = np.empty(nt, dtype=np.int32)
        me.loop_triangles.foreach_get("polygon_index", tp)
        tm = np.empty(nt, dtype=np.int32)
        me.loop_triangles.foreach_get("material_index", tm)

        # materials (object slots win over mesh slots) -> IR materials + colour descriptions
        slots = [s.material for s in bpy_obj.material_slots] if len(bpy_obj.material_slots) else list(me.materials)
        if not slots:
            slots = [None]
        tm = np.clip(tm, 0, len(slots) - 1)
        used = np.unique(tm)
        remap = np.full(len(slots), -1, dtype=np.int32)
        remap[used] = np.arange(len(used), dtype=np.int32)
        mats = []
        for i in used:
            key = (slots[i].as_pointer() if slots[i] is not None else 0, 0)
            if key not in self._material_cache:
                self._material_cache[key] = self.material(slots[i], f"object {name!r}")
            m_ir, col_desc = self._material_cache[key]
            col_desc = dict(col_desc)  # per-mesh copy (attribute names are resolved per mesh)
            if col_desc.pop("emission_from_color", 0.0):
                self.note(f"object {name!r}: emission driven by the base colour is only parsed on point clouds")
            mats.append((m_ir, col_desc))
        faces_material = remap[tm] if len(used) > 1 else None

        # shading: flat, smooth, or mixed (split vertices where corner normals differ)
        smooth_face = np.empty(len(me.polygons), dtype=bool)
        me.polygons.foreach_get("use_smooth", smooth_face)
        keys: list[np.ndarray] = [tris.reshape(-1, 1).astype(np.int64)]
        smooth = bool(smooth_face.any())
        if smooth:
            nl = len(me.loops)
            cn = np.empty(nl * 3, dtype=np.float32)
            me.corner_normals.foreach_get("vector", cn)
            cn = cn.reshape(nl, 3)[tri_loops.ravel()]
            vn = np.empty(nv * 3, dtype=np.float32)
            me.vertex_normals.foreach_get("vector", vn)
            vn = vn.reshape(nv, 3)[tris.ravel()]
            if np.max(np.abs(cn - vn)) > 1e-4:
                keys.append(np.round(cn.astype(np.float64) * 1e3).astype(np.int64))

        # colour attributes used by the materials
        attr_cache: dict[str, tuple[str, np.ndarray] | None] = {}
        corner_color_names: list[str] = []
        for _mat, col in mats:
            if col["kind"] == "attribute":
                nm = col["name"] or me.color_attributes.default_color_name or me.color_attributes.active_color_name
                col["name"] = nm
                if nm not in attr_cache:
                    attr_cache[nm] = self._read_color_attribute(me, nm, f"object {name!r}")
                got = attr_cache[nm]
                if got is not None and got[0] != "POINT" and nm not in corner_color_names:
                    corner_color_names.append(nm)

        def per_corner(nm: str) -> np.ndarray:
            dom, data = attr_cache[nm]  # type: ignore[misc]
            if dom == "POINT":
                return data[tris.ravel()]
            if dom == "CORNER":
                return data[tri_loops.ravel()]
            return np.repeat(data[tp], 3, axis=0)  # FACE

        for nm in corner_color_names:
            keys.append(np.round(per_corner(nm).astype(np.float64) * 1e5).astype(np.int64))

        corner_vertex = tris.ravel()
        # vertex splitting: a vertex keeps its index for its first (normal, colour) variant; other
        # variants become new vertices appended at the end
        src_corner: np.ndarray | None = None  # for every output vertex, a corner it comes from (or -1)
        new_faces = tris.astype(np.int32)
        new_verts = verts
        if len(keys) > 1:
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
            new_verts = np.concatenate([verts, verts[key_vertex[extra]]], axis=0)
            src_corner = np.full(len(new_verts), -1, dtype=np.int64)
            src_corner[new_id] = first

        def vertex_values(nm: str) -> np.ndarray:
            dom, data = attr_cache[nm]  # type: ignore[misc]
            if dom == "POINT" and (src_corner is None or len(new_verts) == nv):
                return data
            out = np.ones((len(new_verts), 4), dtype=np.float32)
            if dom == "POINT":
                out[:nv] = data
            if src_corner is None:
                pc = per_corner(nm)
                out[corner_vertex] = pc
                return out
            ok = src_corner >= 0
            out[ok] = per_corner(nm)[src_corner[ok]]
            return out

        # UV layers
        uv_cache: dict[str, Any] = {}

        def faces_uv(layer: str) -> Any:
            lay = None
            if layer:
                lay = me.uv_layers.get(layer)
                if lay is None:
                    self.note(f"object {name!r}: UV map {layer!r} not found, used the render UV map")
            if lay is None:
                lay = next((u for u in me.uv_layers if u.active_render), None) or me.uv_layers.active
            if lay is None:
                return None
            if lay.name not in uv_cache:
                uv = np.empty(len(me.loops) * 2, dtype=np.float32)
                lay.uv.foreach_get("vector", uv)
                uv_cache[lay.name] = FacesUV(uv.reshape(-1, 2)[tri_loops])
            return uv_cache[lay.name]

        ir_mats, ir_cols = [], []
        for m, col in mats:
            ir_mats.append(m)
            c = None
            if col["kind"] == "texture":
                uvm = faces_uv(col["uv"])
                if uvm is None:
                    self.note(f"object {name!r}: image texture without a UV map, used a uniform colour")
                else:
                    kind, data, cs = col["image"]
                    if col.get("opaque"):
                        kind, data = _opaque_image(kind, data)
                    if kind == "file":
                        c = FileTextureColors(data, uvm, color_space=cs, interpolation=col["interpolation"])
                    else:
                        c = TextureColors(data, uvm, color_space=cs, interpolation=col["interpolation"])
            elif col["kind"] == "attribute":
                if attr_cache.get(col["name"]) is not None:
                    vals = vertex_values(col["name"])
                    if float(vals[:, :3].max(initial=0.0)) > 1.0 or float(vals.min(initial=0.0)) < 0.0:
                        self.note(f"object {name!r}: colour attribute {col['name']!r} clipped to [0, 1]")
                    vals = np.clip(vals, 0.0, 1.0)
                    c = VertexColors(vals[:, :3] if col.get("opaque") else vals, color_space="linear")
                else:
                    self.note(f"object {name!r}: colour attribute {col['name']!r} not found, used white")
                    c = UniformColors((1.0, 1.0, 1.0), color_space="linear")
            if c is None:
                rgba = np.asarray(col.get("rgba", (0.8, 0.8, 0.8, 1.0)), dtype=np.float64)
                rgb, k = _rgb01(rgba[:3])
                if k > 1.0:
                    self.note(f"object {name!r}: base colour > 1 normalised to [0, 1]")
                # the 4th component of a Base Color socket does not affect shading (Alpha is its own input)
                c = UniformColors(tuple(rgb), color_space="linear")
            ir_cols.append(c)

        # world transform: rotation + translation as the pose, scale/shear/reflection baked in
        r, s, t = _decompose(matrix)
        if not _is_identity(s):
            new_verts = new_verts @ s.T
            if np.linalg.det(s) < 0:
                new_faces = new_faces[:, ::-1].copy()
                ir_cols = [_flip_uv_colors(c) for c in ir_cols]
        uv_default = faces_uv("") if len(me.uv_layers) else None
        if uv_default is not None and np.linalg.det(s) < 0:
            uv_default = FacesUV(uv_default.data[:, ::-1])
        return {
            "vertices": new_verts,
            "faces": new_faces,
            "material": ir_mats if len(ir_mats) > 1 else ir_mats[0],
            "colors": ir_cols if len(ir_cols) > 1 else ir_cols[0],
            "faces_material": faces_material,
            "uv_map": uv_default,
            "smooth": smooth,
            "rotation_mode": "rotmat",
            "rotation": r,
            "translation": t,
        }

    def points_instance(self, bpy_obj: Any, matrix: np.ndarray, name: str, pend: _Pending) -> None:
        """A point cloud (native points, e.g. Geometry Nodes Mesh to Points) -> IR PointCloud."""
        from blendify_core.ir.colors import UniformColors, VertexColors

        pc = bpy_obj.data
        attrs = pc.attributes
        n = len(attrs["position"].data) if "position" in attrs else 0
        if n == 0:
            return
        pos = np.empty(n * 3, dtype=np.float32)
        attrs["position"].data.foreach_get("vector", pos)
        verts = pos.reshape(n, 3).astype(np.float64)
        if "radius" in attrs:
            rad = np.empty(n, dtype=np.float32)
            attrs["radius"].data.foreach_get("value", rad)
        else:
            rad = np.full(n, 0.01, dtype=np.float32)
        slots = [s.material for s in bpy_obj.material_slots] if len(bpy_obj.material_slots) else list(pc.materials)
        mat = slots[0] if slots else None
        if len(slots) > 1:
            self.note(f"point cloud {name!r}: {len(slots)} materials, used the first")
        key = (mat.as_pointer() if mat is not None else 0, 0)
        if key not in self._material_cache:
            self._material_cache[key] = self.material(mat, f"point cloud {name!r}")
        m_ir, col = self._material_cache[key]
        col = dict(col)
        emission = float(col.pop("emission_from_color", 0.0))
        colors: Any = None
        if col["kind"] == "attribute":
            nm = col["name"] or pc.color_attributes.default_color_name or pc.color_attributes.active_color_name
            attr = attrs.get(nm) if nm else None
            if attr is not None and attr.domain == "POINT" and attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
                buf = np.empty(n * 4, dtype=np.float32)
                attr.data.foreach_get("color", buf)
                colors = VertexColors(np.clip(buf.reshape(n, 4), 0.0, 1.0), color_space="linear")
            else:
                self.note(f"point cloud {name!r}: colour attribute {nm!r} not found, used white")
        elif col["kind"] == "texture":
            self.note(f"point cloud {name!r}: image textures on points not supported, used a uniform colour")
        if colors is None:
            rgba = np.asarray(col.get("rgba", (0.8, 0.8, 0.8, 1.0)), dtype=np.float64)
            rgb, _k = _rgb01(rgba[:3])
            colors = UniformColors(tuple(rgb), color_space="linear")
        r, s, t = _decompose(matrix)
        if not _is_identity(s):
            verts = verts @ s.T
            scale = abs(np.linalg.det(s)) ** (1.0 / 3.0)
            rad = rad * scale
            if not np.allclose(np.linalg.svd(s, compute_uv=False), scale, rtol=1e-5):
                self.note(f"point cloud {name!r}: non-uniform scale, sphere radii scaled by the mean")
        size = 2.0 * rad.astype(np.float64)
        if np.any(size <= 0):
            self.note(f"point cloud {name!r}: points with radius <= 0 dropped")
            keep = size > 0
            verts, size = verts[keep], size[keep]
            if isinstance(colors, VertexColors):
                colors = VertexColors(colors.vertex_colors[keep], color_space="linear")
            if len(verts) == 0:
                return
        point_size: Any = float(size[0]) if np.allclose(size, size[0], rtol=1e-6) else size
        pend.points.append(
            (
                name,
                {
                    "vertices": verts,
                    "material": m_ir,
                    "colors": colors,
                    "point_size": point_size,
                    "particle_emission_strength": emission,
                    "rotation_mode": "rotmat",
                    "rotation": r,
                    "translation": t,
                },
            )
        )

    def _read_color_attribute(self, me: Any, nm: str, where: str) -> tuple[str, np.ndarray] | None:
        attr = me.attributes.get(nm) if nm else None
        if attr is None:
            return None
        if attr.domain not in ("POINT", "CORNER", "FACE"):
            self.note(f"{where}: colour attribute {nm!r} on the {attr.domain} domain not supported")
            return None
        n = len(attr.data)
        if attr.data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
            buf = np.empty(n * 4, dtype=np.float32)
            attr.data.foreach_get("color", buf)  # scene-linear for both storage types
            return attr.domain, buf.reshape(n, 4)
        if attr.data_type == "FLOAT_VECTOR":
            buf = np.empty(n * 3, dtype=np.float32)
            attr.data.foreach_get("vector", buf)
            return attr.domain, np.concatenate([buf.reshape(n, 3), np.ones((n, 1), np.float32)], axis=1)
        if attr.data_type == "FLOAT":
            buf = np.empty(n, dtype=np.float32)
            attr.data.foreach_get("value", buf)
            return attr.domain, np.concatenate([np.repeat(buf[:, None], 3, axis=1), np.ones((n, 1), np.float32)], 1)
        self.note(f"{where}: attribute {nm!r} of type {attr.data_type} is not a colour")
        return None

    # -- lights ----------------------------------------------------------------------------------
    def light(self, obj: Any, matrix: np.ndarray, name: str, pend: _Pending) -> None:
        data = obj.data
        where = f"light {name!r}"
        r, s, t = _decompose(matrix)
        if np.linalg.det(s) < 0:
            self.note(f"{where}: mirrored (negative scale) light transform read without the mirror")
        power = float(data.energy) * 2.0 ** float(getattr(data, "exposure", 0.0))
        rgb = np.asarray(data.color, dtype=np.float64)
        if getattr(data, "use_temperature", False):
            rgb = rgb * np.asarray(data.temperature_color, dtype=np.float64)
        if getattr(data, "use_nodes", False) and data.node_tree is not None:
            factor = self._light_nodes(data.node_tree, where)
            if factor is not None:
                power *= factor[0]
                rgb = rgb * factor[1]
        color, k = _rgb01(rgb)
        power *= k
        normalize = bool(getattr(data, "normalize", True))
        common = {
            "color": tuple(float(x) for x in color),
            "use_shadow": bool(data.use_shadow),
            "rotation_mode": "rotmat",
            "rotation": r,
            "translation": t,
            "color_space": "linear",
        }
        scale = np.linalg.norm(matrix[:3, :3], axis=0)
        if data.type in ("POINT", "SPOT"):
            radius = float(data.shadow_soft_size)
            if not normalize and radius > 0:
                power *= math.pi * radius * radius
            if data.type == "POINT":
                pend.lights.append((name, "point", {"strength": power, "shadow_soft_size": radius, **common}))
            else:
                size = float(np.clip(data.spot_size, math.radians(1.0), math.pi))
                if abs(size - data.spot_size) > 1e-6:
                    self.note(f"{where}: spot_size {math.degrees(data.spot_size):g} deg clipped")
                if not np.allclose(scale, scale[0], rtol=1e-5):
                    self.note(f"{where}: non-uniform scale of a spot cone ignored")
                pend.lights.append(
                    (
                        name,
                        "spot",
                        {
                            "strength": power,
                            "spot_size": size,
                            "spot_blend": float(np.clip(data.spot_blend, 0.0, 1.0)),
                            "shadow_soft_size": radius,
                            **common,
                        },
                    )
                )
        elif data.type == "SUN":
            if not normalize and data.angle > 0:
                self.note(f"{where}: sun with normalize off read as normalized")
            pend.lights.append(
                (name, "sun", {"strength": power, "angular_diameter": float(np.clip(data.angle, 0, math.pi)), **common})
            )
        elif data.type == "AREA":
            sx, sy = float(scale[0]), float(scale[1])
            shape = data.shape
            a = float(data.size) * sx
            b = float(data.size_y if shape in ("RECTANGLE", "ELLIPSE") else data.size) * sy
            if shape in ("SQUARE", "RECTANGLE"):
                ir_shape = "square" if abs(a - b) <= 1e-9 * max(a, b) and shape == "SQUARE" else "rectangle"
                area = a * b
            else:
                ir_shape = "circle" if abs(a - b) <= 1e-9 * max(a, b) and shape == "DISK" else "ellipse"
                area = math.pi * a * b / 4.0
            if not normalize:
                power *= area
            if abs(float(getattr(data, "spread", math.pi)) - math.pi) > 1e-6:
                self.note(f"{where}: area light spread {math.degrees(data.spread):g} deg read as 180 deg")
            if a <= 0 or b <= 0:
                self.note(f"{where}: zero-size area light skipped")
                return
            size: Any = a if ir_shape in ("square", "circle") else (a, b)
            pend.lights.append((name, "area", {"shape": ir_shape, "size": size, "strength": power, **common}))
        else:
            self.note(f"{where}: light type {data.type} not supported")

    def _light_nodes(self, tree: Any, where: str) -> tuple[float, np.ndarray] | None:
        """(strength, colour) of a light's Emission node with constant inputs, or None (noted)."""
        outs = [n for n in tree.nodes if n.type == "OUTPUT_LIGHT" and n.target in ("ALL", "CYCLES")]
        out = ([n for n in outs if n.is_active_output] or outs or [None])[0]
        src = self._link_from(out.inputs["Surface"]) if out is not None else None
        if src is None:
            return 0.0, np.ones(3)  # a light node tree with nothing connected emits nothing
        node = src[0]
        if node.type != "EMISSION" or node.inputs["Color"].is_linked or node.inputs["Strength"].is_linked:
            self.note(f"{where}: light node tree ({node.bl_idname}) not parsed")
            return None
        return float(node.inputs["Strength"].default_value), np.asarray(node.inputs["Color"].default_value)[:3]

    # -- world / camera --------------------------------------------------------------------------
    def world(self, world: Any, pend: _Pending) -> None:
        """World -> background light (colour x strength) and/or environment map (Background nodes,
        possibly summed by Add Shader nodes)."""
        if world is None:
            return
        where = f"world {world.name!r}"
        tree = world.node_tree
        if tree is None:
            c, k = _rgb01(world.color)
            if k * float(c.max()) > 0:
                pend.world.append(("background", {"strength": k, "color": tuple(c), "color_space": "linear"}))
            return
        outs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD" and n.target in ("ALL", "CYCLES")]
        out = ([n for n in outs if n.is_active_output] or outs or [None])[0]
        if out is None:
            return
        if out.inputs.get("Volume") is not None and out.inputs["Volume"].is_linked:
            self.note(f"{where}: world volume not parsed")
        backgrounds: list[Any] = []
        stack = [out.inputs["Surface"]]
        while stack:
            src = self._link_from(stack.pop())
            if src is None:
                continue
            node, _ = src
            if node.type == "ADD_SHADER":
                stack.extend(reversed(list(node.inputs)))
            elif node.type == "BACKGROUND":
                backgrounds.append(node)
            else:
                self.note(f"{where}: world shader {node.bl_idname} not parsed")
        colour_done = env_done = False
        for node in backgrounds:
            strength = float(node.inputs["Strength"].default_value)
            if node.inputs["Strength"].is_linked:
                self.note(f"{where}: world strength driven by nodes, used its default value")
            col = node.inputs["Color"]
            csrc = self._link_from(col)
            if csrc is not None and csrc[0].type == "TEX_ENVIRONMENT":
                env = csrc[0]
                if env_done:
                    self.note(f"{where}: more than one environment texture, kept the first")
                    continue
                if env.image is None or env.projection != "EQUIRECTANGULAR":
                    self.note(f"{where}: environment texture without an image or not equirectangular")
                    continue
                img = self.image_source(env.image, where)
                if img is None or strength <= 0:
                    continue
                kind, data, cs = img
                spec: dict[str, Any] = {"image_or_path": data, "strength": strength, "color_space": cs}
                rot = self._environment_rotation(env, where)
                if rot is not None:
                    spec.update(rotation_mode="rotmat", rotation=rot)
                pend.world.append(("environment", spec))
                env_done = True
                continue
            if csrc is not None:
                self.note(f"{where}: background colour driven by a {csrc[0].bl_idname} node, used its default value")
            c, k = _rgb01(col.default_value)
            if strength * k * float(c.max()) <= 0:
                continue
            if colour_done:
                self.note(f"{where}: several uniform backgrounds, kept the first")
                continue
            pend.world.append(("background", {"strength": strength * k, "color": tuple(c), "color_space": "linear"}))
            colour_done = True

    def _environment_rotation(self, env: Any, where: str) -> np.ndarray | None:
        """The IR rotation of an environment texture fed by Texture Coordinate (Generated) -> Mapping
        (type VECTOR / POINT, rotation only), or None for the default mapping."""
        vec = env.inputs.get("Vector")
        src = self._link_from(vec) if vec is not None else None
        if src is None:
            return None
        node, _ = src
        if node.type == "TEX_COORD":
            return None
        if node.type == "MAPPING" and node.vector_type in ("VECTOR", "POINT"):
            linked = [s.name for s in node.inputs if s.is_linked and s.name != "Vector"]
            if linked:
                self.note(f"{where}: environment Mapping inputs {linked} driven by nodes, not parsed")
            import mathutils

            euler = mathutils.Euler(tuple(node.inputs["Rotation"].default_value), "XYZ")
            inv = np.array(euler.to_matrix(), dtype=np.float64)
            # the mapping rotates the lookup direction by the INVERSE of the map's rotation
            return inv.T
        self.note(f"{where}: environment texture coordinates from a {node.bl_idname} node not parsed")
        return None

    def camera(self, sc: Any, obj_eval: Any, pend: _Pending) -> None:
        cam = obj_eval.data
        where = f"camera {obj_eval.name!r}"
        rd = sc.render
        w, h, pct = int(rd.resolution_x), int(rd.resolution_y), int(rd.resolution_percentage)
        if cam.type not in ("PERSP", "ORTHO"):
            self.note(f"{where}: {cam.type.lower()} camera not supported, no camera imported")
            return
        if cam.dof.use_dof:
            self.note(f"{where}: depth of field not parsed")
        if rd.use_border:
            self.note(f"{where}: render border not parsed")
        intr = blender_camera_intrinsics(cam, w, h, rd.pixel_aspect_x, rd.pixel_aspect_y)
        r, t = _rotation_only(_mat(obj_eval.matrix_world))
        pose = {"rotation_mode": "rotmat", "rotation": r, "translation": t}
        common = {
            "near": float(cam.clip_start),
            "far": float(max(cam.clip_end, cam.clip_start * (1 + 1e-6))),
            "resolution_percentage": pct,
            "tag": _saved_tag(obj_eval) or obj_eval.name.strip() or "camera",
        }
        if cam.type == "ORTHO":
            if abs(intr["ycor"] - 1.0) > 1e-9:
                self.note(f"{where}: orthographic camera with non-square pixels read with square pixels")
            pend.camera = (
                "ortho",
                {
                    "resolution": (w, h),
                    "ortho_scale": intr["ortho_scale"],
                    "center": (intr["cx"], intr["cy"]),
                    **common,
                    **pose,
                },
            )
        else:
            k = np.array([[intr["fx"], 0.0, intr["cx"]], [0.0, intr["fy"], intr["cy"]], [0.0, 0.0, 1.0]])
            pend.camera = ("persp", {"resolution": (w, h), "K": k, **common, **pose})


def _opaque_image(kind: str, data: Any) -> tuple[str, Any]:
    """An image whose alpha Blender does not use: files with a real alpha channel are read and their
    RGB kept in memory (the IR would otherwise make the surface transparent)."""
    from blendify_core.ir.colors import load_image

    img = load_image(data) if kind == "file" else data
    if img.shape[2] != 4:
        return kind, data
    full = 255 if img.dtype == np.uint8 else 1.0
    if kind == "file" and bool(np.all(img[..., 3] >= full)):
        return kind, data
    return "pixels", np.ascontiguousarray(img[..., :3])


def _flip_uv_colors(c: Any) -> Any:
    from blendify_core.ir.colors import FacesUV, FileTextureColors, TextureColors

    if isinstance(c, FileTextureColors):
        return FileTextureColors(c.texture_path, FacesUV(c.uv_map.data[:, ::-1]), c.color_space, c.interpolation)
    if isinstance(c, TextureColors):
        return TextureColors(c.texture, FacesUV(c.uv_map.data[:, ::-1]), c.color_space, c.interpolation)
    return c


def _render_visibility(bpy: Any, new_ids: list[Any], view_layer: Any) -> Iterator[str]:
    """Make the appended (temporary) data evaluate like a render in the viewport depsgraph: render
    visibility of objects and collections, no view-layer hiding, render levels of modifiers."""
    for idb in new_ids:
        if isinstance(idb, bpy.types.Object):
            idb.hide_viewport = bool(idb.hide_render)
            idb.show_instancer_for_viewport = bool(idb.show_instancer_for_render)
            for md in idb.modifiers:
                md.show_viewport = bool(md.show_render)
                if md.type in ("SUBSURF", "MULTIRES"):
                    md.levels = md.render_levels
            for psys in idb.particle_systems:
                if psys.settings.render_type == "PATH" or psys.settings.type == "HAIR":
                    yield f"object {idb.name!r}: hair particles not parsed"
                if psys.settings.display_percentage != 100:
                    psys.settings.display_percentage = 100
        elif isinstance(idb, bpy.types.Collection):
            idb.hide_viewport = bool(idb.hide_render)
    stack = [view_layer.layer_collection]
    while stack:
        lc = stack.pop()
        lc.hide_viewport = False
        stack.extend(lc.children)
    for ob in view_layer.objects:
        if not ob.hide_render and ob.hide_get(view_layer=view_layer):
            ob.hide_set(False, view_layer=view_layer)


def _saved_tag(obj: Any) -> str | None:
    """The IR tag stored by :func:`export_blend` on an object (custom property), or None."""
    orig = getattr(obj, "original", None) or obj
    tag = orig.get(TAG_PROPERTY)
    return tag.strip() if isinstance(tag, str) and tag.strip() else None


def _unique_tag(base: str, taken: set[str]) -> str:
    base = base.strip() or "Object"
    tag, n = base, 1
    while tag in taken:
        tag = f"{base}.{n:03d}"
        n += 1
    taken.add(tag)
    return tag


_MESH_TYPES = ("MESH", "CURVE", "SURFACE", "META", "FONT")
#: custom property holding the IR tag on objects written by :func:`export_blend`
TAG_PROPERTY = "blendify_tag"


def attach_blend(
    scene: Any,
    path: str | os.PathLike[str],
    with_camera: bool = False,
    *,
    scene_name: str | None = None,
    with_world: bool | None = None,
    texture_dir: str | os.PathLike[str] | None = None,
    warn: bool = True,
) -> AttachedBlend:
    """Append a .blend's content into the IR ``scene``; returns the added renderables (see module docs).

    Args:
        scene: the :class:`blendify_core.ir.scene.Scene` to extend.
        path: the .blend file (never opened as the main file; embedded Python never runs).
        with_camera: also replace ``scene.camera`` by the file's scene camera.
        scene_name: which scene of the file to import (default: the only one, or the first by name, with a
            warning).
        with_world: import the world's background (None: only when ``scene`` has no background or
            environment yet; True: replace it; False: never).
        texture_dir: where PACKED images are unpacked (default: :func:`default_texture_cache_dir`).
        warn: emit one :class:`BlendAttachWarning` listing what could not be parsed.
    """
    from blendify_core.ir.scene import Scene

    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core Scene, got {type(scene).__name__}")
    if not isinstance(with_camera, bool):
        raise InvalidSceneError(f"with_camera: expected True or False, got {with_camera!r}")
    if with_world is not None and not isinstance(with_world, bool):
        raise InvalidSceneError(f"with_world: expected True, False or None, got {with_world!r}")
    if scene_name is not None and not isinstance(scene_name, str):
        raise InvalidSceneError(f"scene_name: expected a scene name (str) or None, got {scene_name!r}")
    if texture_dir is not None and not isinstance(texture_dir, (str, os.PathLike)):
        raise InvalidSceneError(f"texture_dir: expected a directory path or None, got {texture_dir!r}")
    p = check_blend_path(path)
    from . import _runtime

    bpy = _bpy()
    with _runtime.BPY_LOCK, _runtime.capture_output("attach .blend") as cap:
        with _runtime.engine_errors(f"attach_blend({str(p)!r})", cap):
            pend, parser, scene_label = _parse_blend(bpy, scene, p, with_camera, scene_name, with_world, texture_dir)
    return _commit(scene, p, pend, parser, scene_label, warn, with_camera)


def _parse_blend(
    bpy: Any,
    scene: Any,
    p: Path,
    with_camera: bool,
    scene_name: str | None,
    with_world: bool | None,
    texture_dir: str | os.PathLike[str] | None,
) -> tuple[_Pending, _Parser, str]:
    parser = _Parser(bpy, p, texture_dir)
    pend = _Pending()
    with scripts_auto_execute_disabled(), _loaded_blend(p) as (scenes, removed, new_ids):
        parser.notes.extend(removed)
        if scene_name is None:
            scene_label, sc = scenes[0]
            if len(scenes) > 1:
                parser.note(
                    f"the file has {len(scenes)} scenes {[n for n, _ in scenes]}; imported {scene_label!r}, the "
                    "first by name (pass scene_name= to choose)"
                )
        else:
            match = [(n, s) for n, s in scenes if n == scene_name]
            if not match:
                raise InvalidSceneError(
                    f"scene_name: {str(p)!r} has no scene {scene_name!r}; its scenes: {[n for n, _ in scenes]}"
                )
            scene_label, sc = match[0]
        view_layer = next((vl for vl in sc.view_layers if vl.use), sc.view_layers[0])
        for msg in _render_visibility(bpy, new_ids, view_layer):
            parser.note(msg)
        with bpy.context.temp_override(scene=sc, view_layer=view_layer):
            dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        unsupported: dict[str, int] = {}
        # objects whose evaluated geometry also comes as their own mesh component (curves with a bevel,
        # text, ...): the component is parsed, the object's own to_mesh() would duplicate it
        own_mesh: set[str] = set()
        for inst in dg.object_instances:
            if inst.is_instance and inst.parent is not None and inst.object.type == "MESH":
                if inst.parent.original == inst.object.original:
                    own_mesh.add(inst.object.original.name)
        for inst in dg.object_instances:
            obj = inst.object
            typ = obj.type
            if typ in ("EMPTY", "CAMERA", "ARMATURE", "LATTICE", "SPEAKER"):
                continue
            if not inst.is_instance and typ in ("CURVE", "SURFACE", "FONT", "META") and obj.original.name in own_mesh:
                continue
            orig = obj.original if obj.original is not None else obj
            parent = inst.parent.original if (inst.is_instance and inst.parent is not None) else None
            # a geometry component of the object itself (e.g. points made by Geometry Nodes) is not an
            # instance of another object
            own_component = parent is not None and parent == orig
            name = orig.name if parent is None or own_component else f"{parent.name}/{orig.name}"
            saved_tag = _saved_tag(obj)
            if saved_tag is not None and (parent is None or own_component):
                name = saved_tag
            if parent is None and orig.hide_render:
                continue
            if parent is None and orig.parent is not None and orig.parent.instance_type in ("VERTS", "FACES"):
                continue  # children of vertex/face instancers render only as instances
            if typ != "LIGHT" and not inst.show_self:
                continue  # e.g. a vertex/face/particle instancer whose own geometry does not render
            matrix = _mat(inst.matrix_world)
            n_before = len(pend.meshes) + len(pend.points)
            if typ in _MESH_TYPES:
                parser.mesh_instance(obj, matrix, name, pend)
            elif typ == "POINTCLOUD":
                parser.points_instance(obj, matrix, name, pend)
            elif typ == "LIGHT":
                parser.light(obj, matrix, name, pend)
                continue
            else:
                unsupported[typ] = unsupported.get(typ, 0) + 1
                continue
            if len(pend.meshes) + len(pend.points) > n_before:
                spec = (pend.points[-1] if typ == "POINTCLOUD" else pend.meshes[-1])[1]
                spec["emit_shadows"] = bool(orig.visible_shadow)
                if orig.is_shadow_catcher:
                    parser.note(f"object {name!r}: shadow catcher read as a normal surface")
                if not orig.visible_camera:
                    parser.note(f"object {name!r}: hidden from the camera in Blender, visible in the IR")
        for typ, n in unsupported.items():
            parser.note(f"{n} object(s) of type {typ} not parsed (kept for Cycles only)")
        if with_world or (with_world is None and scene.lights.background is None and scene.lights.environment is None):
            parser.world(sc.world, pend)
        if with_camera:
            if sc.camera is None:
                raise InvalidSceneError(f"with_camera: scene {sc.name!r} of {str(p)!r} has no camera")
            parser.camera(sc, sc.camera.evaluated_get(dg), pend)
    return pend, parser, scene_label


def _commit(
    scene: Any, p: Path, pend: _Pending, parser: _Parser, scene_label: str, warn: bool, with_camera: bool
) -> AttachedBlend:
    """Add the parsed objects to the IR scene (all or nothing)."""
    added_r: list[Any] = []
    added_l: list[Any] = []
    taken_r = set(scene.renderables.keys())
    taken_l = set(scene.lights.keys())
    old_bg, old_env, old_cam = scene.lights.background, scene.lights.environment, scene.camera
    try:
        for name, spec in pend.meshes + pend.points:
            emit = spec.pop("emit_shadows", True)
            add_r = scene.renderables.add_pointcloud if "point_size" in spec else scene.renderables.add_mesh
            tag = _unique_tag(name, taken_r)
            try:
                r = add_r(tag=tag, **spec)
            except InvalidSceneError as exc:  # data the IR rejects: skip this object, keep the rest
                parser.note(f"object {name!r} not imported: {exc}")
                taken_r.discard(tag)
                continue
            r.emit_shadows = emit
            added_r.append(r)
        for name, kind, spec in pend.lights:
            add = {
                "point": scene.lights.add_point,
                "sun": scene.lights.add_sun,
                "spot": scene.lights.add_spot,
                "area": scene.lights.add_area,
            }[kind]
            tag = _unique_tag(name, taken_l)
            try:
                added_l.append(add(tag=tag, **spec))
            except InvalidSceneError as exc:
                parser.note(f"light {name!r} not imported: {exc}")
                taken_l.discard(tag)
        background = None
        for kind, spec in pend.world:
            if kind == "environment":
                background = scene.lights.set_environment_map(**spec)
            else:
                background = scene.lights.set_background_light(**spec)
        camera = None
        if pend.camera is not None:
            kind, spec = pend.camera
            if kind == "ortho":
                camera = scene.set_orthographic_camera(**spec)
            else:
                camera = scene.set_perspective_camera(**spec)
    except Exception:
        for r in added_r:
            scene.renderables.remove(r)
        for lt in added_l:
            scene.lights.remove(lt)
        scene.lights.background, scene.lights.environment = old_bg, old_env
        scene.camera = old_cam
        raise
    if with_camera and camera is None:
        parser.note("no usable camera in the file; scene.camera unchanged")
    scene.attachments.append(Attachment("blend", str(p)))
    result = AttachedBlend(added_r)
    result.path = str(p)
    result.scene_name = scene_label
    result.lights = added_l
    result.camera = camera
    result.background = background
    result.unparsed = list(parser.notes)
    result.texture_dir = str(parser.texture_dir) if parser.texture_dir is not None else None
    if warn and parser.notes:
        lines = "\n  - ".join(parser.notes)
        warnings.warn(
            f"attach_blend({str(p)!r}): {len(parser.notes)} item(s) not (fully) parsed into the IR "
            f"(the file stays attached for Cycles):\n  - {lines}",
            BlendAttachWarning,
            stacklevel=3,
        )
    return result


# ---------------------------------------------------------------------------------------------------
# export
# ---------------------------------------------------------------------------------------------------


def export_blend(scene: Any, path: str | os.PathLike[str], pack_textures: bool = True, **settings: Any) -> Path:
    """Write ``scene`` as a .blend that opens in Blender and renders the same picture.

    The bpy scene is built by the Cycles translator (:func:`blendify_blender.translate.build_scene`,
    which resets the bpy session to an empty factory scene first); in-memory images are always packed,
    texture FILES are packed when ``pack_textures`` (default; otherwise referenced by absolute path),
    each object gets its IR tag as the custom property ``blendify_tag`` (so :func:`attach_blend` gives
    the same tags back), and the file is written with ``bpy.data.libraries.write`` to a temporary name
    then renamed: no ``.blend1`` backup, the main file path and the working directory do not change.
    The built datablocks are removed afterwards. ``settings`` are render settings
    (:func:`blendify_core.pipeline.settings.resolve_settings` keywords, e.g. ``quality="final", samples=64``)
    stored in the file. Returns the written path.
    """
    from blendify_core.ir.scene import Scene
    from blendify_core.pipeline.settings import resolve_settings

    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core Scene, got {type(scene).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidSceneError(f"path: expected a file path ending in .blend, got {type(path).__name__} {path!r}")
    out = Path(path).expanduser()
    if out.suffix.lower() != ".blend":
        raise InvalidSceneError(f"path: expected a file name ending in .blend, got {str(out)!r}")
    if out.is_dir():
        raise InvalidSceneError(f"path: {str(out)!r} is a directory")
    if not isinstance(pack_textures, bool):
        raise InvalidSceneError(f"pack_textures: expected True or False, got {pack_textures!r}")
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera; call scene.set_perspective_camera(...) first")
    try:
        render_settings = resolve_settings(**settings)
    except TypeError as exc:
        raise InvalidSceneError(f"export_blend: unknown render setting(s) {sorted(settings)} ({exc})") from None
    out = out.absolute()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidSceneError(f"path: cannot create the folder {str(out.parent)!r} ({exc})") from None

    from . import _runtime
    from .translate import build_scene

    bpy = _runtime.bpy_module()
    with _runtime.BPY_LOCK:
        built = build_scene(scene, render_settings, reset=True)
        tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp.blend")
        try:
            with _runtime.capture_output("export .blend") as cap, _runtime.engine_errors("export_blend", cap):
                for r in scene.renderables:
                    entry = built.entries.get(r.uid)
                    if entry is not None and entry.objects:
                        entry.objects[0][TAG_PROPERTY] = r.tag
                for light, obj in zip(scene.lights, built.lights.objects):
                    obj[TAG_PROPERTY] = light.tag
                if built.camera_object is not None:
                    built.camera_object[TAG_PROPERTY] = scene.camera.tag
                bl_scene = built.bscene
                for img in _scene_images(bpy, bl_scene):
                    # in-memory images (no file behind them) are always packed, files only when asked
                    in_memory = img.source == "GENERATED" or not (img.filepath_raw or img.filepath)
                    if img.packed_file is None and (in_memory or (pack_textures and img.source == "FILE")):
                        img.pack()
                bpy.data.libraries.write(str(tmp), {bl_scene}, path_remap="ABSOLUTE", fake_user=False, compress=True)
            os.replace(tmp, out)
        except OSError as exc:
            raise RenderError(f"export_blend: could not write {str(out)!r}: {exc}") from exc
        finally:
            if tmp.exists():
                tmp.unlink()
            built.remove()
    return out


def _scene_images(bpy: Any, bl_scene: Any) -> list[Any]:
    """Images used by the objects' materials and the world of ``bl_scene``."""
    seen: dict[int, Any] = {}

    def walk(tree: Any) -> None:
        if tree is None:
            return
        for n in tree.nodes:
            img = getattr(n, "image", None)
            if img is not None and isinstance(img, bpy.types.Image):
                seen[img.as_pointer()] = img
            sub = getattr(n, "node_tree", None)
            if sub is not None and sub.as_pointer() not in seen:
                seen[sub.as_pointer()] = None
                walk(sub)

    for ob in bl_scene.objects:
        for slot in ob.material_slots:
            if slot.material is not None:
                walk(slot.material.node_tree)
        for md in ob.modifiers:
            if md.type == "NODES" and md.node_group is not None:
                walk(md.node_group)
    if bl_scene.world is not None:
        walk(bl_scene.world.node_tree)
    return [i for i in seen.values() if i is not None]
