"""Lights and the world of a .blend -> IR lights, background light and environment map.

- point, sun, spot and area lights of every shape (square, rectangle, disk, ellipse; object scale
  applied to the size) in the IR's units (exposure, ``normalize=False`` and temperature folded into
  strength and colour; Blender's point-light "soft falloff" is not represented: the IR light is the
  sphere light without it, as the Cycles translator renders it); a light node tree counts when it is an
  Emission node with constant inputs;
- the world: Background colour x strength -> background light, an Environment Texture (with a Mapping
  rotation) -> environment map, both when summed by an Add Shader.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes, decompose, rgb01
from blendify_blender.blendfile.images import ImageReader
from blendify_blender.blendfile.nodes import link_from

__all__ = ["light_spec", "world_specs"]


def light_spec(obj: Any, matrix: np.ndarray, name: str, notes: Notes) -> tuple[str, dict[str, Any]] | None:
    """(IR light kind, ``add_<kind>`` keywords) of an evaluated light object, or None (noted)."""
    data = obj.data
    where = f"light {name!r}"
    r, s, t = decompose(matrix)
    if np.linalg.det(s) < 0:
        notes.add(f"{where}: mirrored (negative scale) light transform read without the mirror")
    power, color = _power_and_color(data, where, notes)
    common = {
        "color": tuple(float(x) for x in color),
        "use_shadow": bool(data.use_shadow),
        "rotation_mode": "rotmat",
        "rotation": r,
        "translation": t,
        "color_space": "linear",
    }
    normalize = bool(getattr(data, "normalize", True))
    scale = np.linalg.norm(matrix[:3, :3], axis=0)
    if data.type in ("POINT", "SPOT"):
        return _point_or_spot(data, power, normalize, scale, common, where, notes)
    if data.type == "SUN":
        if not normalize and data.angle > 0:
            notes.add(f"{where}: sun with normalize off read as normalized")
        return "sun", {"strength": power, "angular_diameter": float(np.clip(data.angle, 0, math.pi)), **common}
    if data.type == "AREA":
        return _area(data, power, normalize, scale, common, where, notes)
    notes.add(f"{where}: light type {data.type} not supported")
    return None


def _power_and_color(data: Any, where: str, notes: Notes) -> tuple[float, np.ndarray]:
    """Blender power (W) with the exposure, temperature and a constant node tree folded in, and a [0, 1]
    colour (a colour > 1 scales the power)."""
    power = float(data.energy) * 2.0 ** float(getattr(data, "exposure", 0.0))
    rgb = np.asarray(data.color, dtype=np.float64)
    if getattr(data, "use_temperature", False):
        rgb = rgb * np.asarray(data.temperature_color, dtype=np.float64)
    if getattr(data, "use_nodes", False) and data.node_tree is not None:
        factor = _light_nodes(data.node_tree, where, notes)
        if factor is not None:
            power *= factor[0]
            rgb = rgb * factor[1]
    color, k = rgb01(rgb)
    return power * k, color


def _light_nodes(tree: Any, where: str, notes: Notes) -> tuple[float, np.ndarray] | None:
    """(strength, colour) of a light's Emission node with constant inputs, or None (noted)."""
    outs = [n for n in tree.nodes if n.type == "OUTPUT_LIGHT" and n.target in ("ALL", "CYCLES")]
    out = ([n for n in outs if n.is_active_output] or outs or [None])[0]
    src = link_from(out.inputs["Surface"]) if out is not None else None
    if src is None:
        return 0.0, np.ones(3)  # a light node tree with nothing connected emits nothing
    node = src[0]
    if node.type != "EMISSION" or node.inputs["Color"].is_linked or node.inputs["Strength"].is_linked:
        notes.add(f"{where}: light node tree ({node.bl_idname}) not parsed")
        return None
    return float(node.inputs["Strength"].default_value), np.asarray(node.inputs["Color"].default_value)[:3]


def _point_or_spot(
    data: Any, power: float, normalize: bool, scale: np.ndarray, common: dict[str, Any], where: str, notes: Notes
) -> tuple[str, dict[str, Any]]:
    radius = float(data.shadow_soft_size)
    if not normalize and radius > 0:
        power *= math.pi * radius * radius
    if data.type == "POINT":
        return "point", {"strength": power, "shadow_soft_size": radius, **common}
    size = float(np.clip(data.spot_size, math.radians(1.0), math.pi))
    if abs(size - data.spot_size) > 1e-6:
        notes.add(f"{where}: spot_size {math.degrees(data.spot_size):g} deg clipped")
    if not np.allclose(scale, scale[0], rtol=1e-5):
        notes.add(f"{where}: non-uniform scale of a spot cone ignored")
    return "spot", {
        "strength": power,
        "spot_size": size,
        "spot_blend": float(np.clip(data.spot_blend, 0.0, 1.0)),
        "shadow_soft_size": radius,
        **common,
    }


def _area(
    data: Any, power: float, normalize: bool, scale: np.ndarray, common: dict[str, Any], where: str, notes: Notes
) -> tuple[str, dict[str, Any]] | None:
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
        notes.add(f"{where}: area light spread {math.degrees(data.spread):g} deg read as 180 deg")
    if a <= 0 or b <= 0:
        notes.add(f"{where}: zero-size area light skipped")
        return None
    size: Any = a if ir_shape in ("square", "circle") else (a, b)
    return "area", {"shape": ir_shape, "size": size, "strength": power, **common}


# ---------------------------------------------------------------------------------------------------
# world
# ---------------------------------------------------------------------------------------------------


def world_specs(world: Any, images: ImageReader, notes: Notes) -> list[tuple[str, dict[str, Any]]]:
    """World -> [("background" | "environment", keywords)]: a background light (colour x strength) and/or
    an environment map (Background nodes, possibly summed by Add Shader nodes)."""
    if world is None:
        return []
    where = f"world {world.name!r}"
    tree = world.node_tree
    if tree is None:
        c, k = rgb01(world.color)
        if k * float(c.max()) > 0:
            return [("background", {"strength": k, "color": tuple(c), "color_space": "linear"})]
        return []
    out_specs: list[tuple[str, dict[str, Any]]] = []
    colour_done = env_done = False
    for node in _background_nodes(tree, where, notes):
        strength = float(node.inputs["Strength"].default_value)
        if node.inputs["Strength"].is_linked:
            notes.add(f"{where}: world strength driven by nodes, used its default value")
        col = node.inputs["Color"]
        csrc = link_from(col)
        if csrc is not None and csrc[0].type == "TEX_ENVIRONMENT":
            if env_done:
                notes.add(f"{where}: more than one environment texture, kept the first")
                continue
            spec = _environment(csrc[0], strength, images, where, notes)
            if spec is not None:
                out_specs.append(("environment", spec))
                env_done = True
            continue
        if csrc is not None:
            notes.add(f"{where}: background colour driven by a {csrc[0].bl_idname} node, used its default value")
        c, k = rgb01(col.default_value)
        if strength * k * float(c.max()) <= 0:
            continue
        if colour_done:
            notes.add(f"{where}: several uniform backgrounds, kept the first")
            continue
        out_specs.append(("background", {"strength": strength * k, "color": tuple(c), "color_space": "linear"}))
        colour_done = True
    return out_specs


def _background_nodes(tree: Any, where: str, notes: Notes) -> list[Any]:
    """The Background nodes feeding the active world output, through Add Shader nodes (others noted)."""
    outs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD" and n.target in ("ALL", "CYCLES")]
    out = ([n for n in outs if n.is_active_output] or outs or [None])[0]
    if out is None:
        return []
    if out.inputs.get("Volume") is not None and out.inputs["Volume"].is_linked:
        notes.add(f"{where}: world volume not parsed")
    backgrounds: list[Any] = []
    stack = [out.inputs["Surface"]]
    while stack:
        src = link_from(stack.pop())
        if src is None:
            continue
        node, _ = src
        if node.type == "ADD_SHADER":
            stack.extend(reversed(list(node.inputs)))
        elif node.type == "BACKGROUND":
            backgrounds.append(node)
        else:
            notes.add(f"{where}: world shader {node.bl_idname} not parsed")
    return backgrounds


def _environment(env: Any, strength: float, images: ImageReader, where: str, notes: Notes) -> dict[str, Any] | None:
    """``set_environment_map`` keywords of an equirectangular Environment Texture, or None."""
    if env.image is None or env.projection != "EQUIRECTANGULAR":
        notes.add(f"{where}: environment texture without an image or not equirectangular")
        return None
    img = images.source(env.image, where)
    if img is None or strength <= 0:
        return None
    _kind, data, cs = img
    spec: dict[str, Any] = {"image_or_path": data, "strength": strength, "color_space": cs}
    rot = _environment_rotation(env, where, notes)
    if rot is not None:
        spec.update(rotation_mode="rotmat", rotation=rot)
    return spec


def _environment_rotation(env: Any, where: str, notes: Notes) -> np.ndarray | None:
    """The IR rotation of an environment texture fed by Texture Coordinate (Generated) -> Mapping
    (type VECTOR / POINT, rotation only), or None for the default mapping."""
    vec = env.inputs.get("Vector")
    src = link_from(vec) if vec is not None else None
    if src is None:
        return None
    node, _ = src
    if node.type == "TEX_COORD":
        return None
    if node.type == "MAPPING" and node.vector_type in ("VECTOR", "POINT"):
        linked = [s.name for s in node.inputs if s.is_linked and s.name != "Vector"]
        if linked:
            notes.add(f"{where}: environment Mapping inputs {linked} driven by nodes, not parsed")
        import mathutils  # Blender's math module, only there with bpy

        euler = mathutils.Euler(tuple(node.inputs["Rotation"].default_value), "XYZ")
        inv = np.array(euler.to_matrix(), dtype=np.float64)
        # the mapping rotates the lookup direction by the INVERSE of the map's rotation
        return inv.T
    notes.add(f"{where}: environment texture coordinates from a {node.bl_idname} node not parsed")
    return None
