"""Procedural colours (Checker, Noise, Gradient, Voronoi, any node tree feeding a colour input) baked to an
image texture with Cycles' baker, for the IR (and so for Mitsuba and pyrender).

While the depsgraph is walked, :mod:`.geometry` gives each such colour a uniform placeholder and a
:class:`Baker` request (the file object, its material, the node output feeding the colour). Afterwards
:meth:`Baker.run` bakes each (object, material) once: on the appended copy of the material (removed with
the rest of the load), the output is routed through an Emission shader into a new Material Output and
Cycles bakes EMIT into a ``resolution`` x ``resolution`` float image through the object's render UV map;
the placeholders are replaced by :class:`~blendify_core.ir.colors.TextureColors` on the mesh's UVs. Each
bake is listed as an approximation (resolution-limited, UV-space; an object without a UV map keeps the
uniform colour, said so).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes
from blendify_core.ir.colors import NormalMap, TextureColors, TextureMap

__all__ = ["DEFAULT_BAKE_RESOLUTION", "Baker"]

#: width and height (pixels) of a baked procedural colour
DEFAULT_BAKE_RESOLUTION = 256


@dataclass
class _Request:
    """Names and originals only: the evaluated copies the parse saw do not outlive the bake's evaluation."""

    obj: Any  # the original (appended) object
    material: Any  # the original material
    node_name: str
    node_type: str  # bl_idname
    socket_id: str  # identifier of the output feeding the colour
    placeholder: Any  # the IR colour source (or, for a normal, the IR material) to replace
    where: str
    kind: str = "color"  # or "normal": the object's shading normal as a tangent-space normal map
    param: str = ""  # for a material (placeholder): the IR parameter the bake feeds (normal / roughness / metallic map)


def _route_to_emission(tree: Any, socket: Any) -> list[tuple[Any, Any]]:
    """``socket`` -> an Emission shader -> a new active Material Output of ``tree``; returns the new nodes."""
    emit = tree.nodes.new("ShaderNodeEmission")
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "ALL"
    tree.links.new(socket, emit.inputs["Color"])
    tree.links.new(emit.outputs[0], out.inputs["Surface"])
    for node in tree.nodes:
        if node.type == "OUTPUT_MATERIAL":
            node.is_active_output = node == out
    return [(tree, emit), (tree, out)]


@dataclass
class Baker:
    """Bake requests of one attach and their results (see the module)."""

    notes: Notes
    resolution: int = DEFAULT_BAKE_RESOLUTION
    requests: list[_Request] = field(default_factory=list)
    baked: dict[int, Any] = field(default_factory=dict)  # id(colour placeholder) -> pixels or None
    #: id(material placeholder) -> {IR parameter: pixels}
    baked_params: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)

    def request(self, obj: Any, material: Any, node: Any, socket: Any, placeholder: Any, where: str) -> None:
        """Bake ``socket`` of ``node`` (in ``material``, maybe evaluated copies) for ``obj``'s original."""
        orig_obj = getattr(obj, "original", None) or obj
        orig_mat = getattr(material, "original", None) or material
        self.requests.append(
            _Request(
                orig_obj, orig_mat, str(node.name), str(node.bl_idname), str(socket.identifier), placeholder, where
            )
        )

    def request_normal(self, obj: Any, placeholder: Any, node_type: str, where: str) -> None:
        """Bake ``obj``'s shading normal (bump, procedural normal map) into a tangent-space normal map for
        the IR material ``placeholder`` (a copy used by this object only)."""
        orig_obj = getattr(obj, "original", None) or obj
        self.requests.append(
            _Request(orig_obj, None, "", node_type, "", placeholder, where, kind="normal", param="normal_map")
        )

    def request_map(
        self, obj: Any, material: Any, names: tuple[str, str, str], placeholder: Any, param: str, where: str
    ) -> None:
        """Bake the float output ``names`` = (node name, bl_idname, output identifier) of ``material`` into the
        IR parameter ``param`` (``roughness_map`` / ``metallic_map``) of the material ``placeholder``."""
        orig_obj = getattr(obj, "original", None) or obj
        orig_mat = getattr(material, "original", None) or material
        self.requests.append(_Request(orig_obj, orig_mat, *names, placeholder, where, param=param))

    def run(self, bpy: Any, sc: Any, view_layer: Any) -> None:
        """Bake every request (each (object, material, socket) once)."""
        if not self.requests:
            return
        done: dict[tuple[int, int, int], np.ndarray | None] = {}
        r = sc.render
        r.engine = "CYCLES"
        sc.cycles.samples = 4
        sc.cycles.device = "CPU"
        r.bake.margin = 4
        r.bake.use_clear = True
        for req in self.requests:
            mat_key = req.material.as_pointer() if req.material is not None else 0
            key = (req.obj.as_pointer(), mat_key, hash((req.kind, req.node_name, req.socket_id, req.param)))
            if key not in done:
                done[key] = self._bake(bpy, sc, view_layer, req)
            pixels = done[key]
            if pixels is None:
                continue
            if req.param:
                self.baked_params.setdefault(id(req.placeholder), {})[req.param] = pixels
            else:
                self.baked[id(req.placeholder)] = pixels
            what = {"": "colour", "normal_map": "normal (tangent-space normal map)"}.get(req.param, req.param)
            self.notes.add(
                f"{req.where}: {what} from a {req.node_type} node baked to a {self.resolution}x{self.resolution} "
                "image with Cycles' baker through the render UV map (an approximation: resolution-limited)"
            )

    def _bake(self, bpy: Any, sc: Any, view_layer: Any, req: _Request) -> np.ndarray | None:
        """(n, n, 3) float pixels (row 0 at the top, as the IR's images) of one request, or None (noted)."""
        what = req.param or "colour"
        obj = req.obj
        if getattr(obj.data, "uv_layers", None) is None or not len(obj.data.uv_layers):
            self.notes.add(f"{req.where}: {req.node_type} {what} not baked: the object has no UV map")
            return None
        socket = None
        if req.kind == "color":
            tree = req.material.node_tree
            node = tree.nodes.get(req.node_name) if tree is not None else None
            socket = next(
                (o for o in (node.outputs if node is not None else ()) if o.identifier == req.socket_id), None
            )
            if socket is None:
                self.notes.add(f"{req.where}: {req.node_type} colour not baked (node not found)")
                return None
        n = self.resolution
        img = bpy.data.images.new("bf_bake", n, n, float_buffer=True, alpha=False)
        img.colorspace_settings.name = "Linear Rec.709" if req.kind == "color" else "Non-Color"
        added: list[tuple[Any, Any]] = []
        try:
            for slot in obj.material_slots:  # Cycles bakes every slot into its active image node
                m = slot.material
                if m is not None and m.node_tree is not None:
                    tex = m.node_tree.nodes.new("ShaderNodeTexImage")
                    tex.image = img
                    m.node_tree.nodes.active = tex
                    added.append((m.node_tree, tex))
            if socket is not None:
                added += _route_to_emission(req.material.node_tree, socket)
            obj.hide_viewport = False
            obj.hide_set(False, view_layer=view_layer)
            obj.select_set(True, view_layer=view_layer)
            override = {
                "scene": sc,
                "view_layer": view_layer,
                "object": obj,
                "active_object": obj,
                "selected_objects": [obj],
                "selected_editable_objects": [obj],
            }
            with bpy.context.temp_override(**override):
                if req.kind == "color":
                    bpy.ops.object.bake(type="EMIT", margin=4, use_clear=True, target="IMAGE_TEXTURES")
                else:
                    bpy.ops.object.bake(type="NORMAL", normal_space="TANGENT", margin=4, use_clear=True)
            px = np.empty(n * n * 4, dtype=np.float32)
            img.pixels.foreach_get(px)
            return px.reshape(n, n, 4)[::-1, :, :3].copy()
        except RuntimeError as exc:
            self.notes.add(f"{req.where}: {req.node_type} {what} not baked ({exc}); left as parsed")
            return None
        finally:
            for tree, node in added:
                try:
                    tree.nodes.remove(node)
                except (ReferenceError, RuntimeError):
                    pass
            bpy.data.images.remove(img)

    def apply(self, specs: list[tuple[str, dict[str, Any]]]) -> None:
        """Replace the placeholders in the pending mesh specs by the baked textures on the mesh's UVs (and
        the materials waiting for a normal map by copies with it)."""
        for _name, spec in specs:
            mats = spec["material"] if isinstance(spec["material"], list) else [spec["material"]]
            for i, m in enumerate(mats):
                params = self.baked_params.get(id(m))
                if params:
                    changes = {
                        p: (NormalMap if p == "normal_map" else TextureMap)(np.clip(px, 0.0, 1.0))
                        for p, px in params.items()
                    }
                    mats[i] = m.copy(**changes)
            spec["material"] = mats if isinstance(spec["material"], list) else mats[0]
            cols = spec["colors"] if isinstance(spec["colors"], list) else [spec["colors"]]
            changed = False
            for i, c in enumerate(cols):
                pixels = self.baked.get(id(c))
                if pixels is None or spec.get("uv_map") is None:
                    continue
                cols[i] = TextureColors(np.clip(pixels, 0.0, 1.0), spec["uv_map"], color_space="linear")
                changed = True
            if changed:
                spec["colors"] = cols if isinstance(spec["colors"], list) else cols[0]
