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

The same path bakes a shading normal (Bump, procedural or object/world-space Normal Map: Cycles' NORMAL
bake in tangent space -> the material's ``normal_map``) and every Principled float input driven by nodes
(:meth:`Baker.request_map`): into the IR's texture map where it has one (``roughness_map``,
``metallic_map``), else into the parameter's one value, the bake's area-weighted mean over the object's
surface (IOR, Coat Weight, Transmission Weight, Emission Strength, Alpha, ...; named in the warning).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes, rgb01
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
    param: str = ""  # for a material (placeholder): the IR parameter the bake feeds ("normal_map" or a float)


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
    #: id(material placeholder) -> {IR parameter: (pixels, request)}
    baked_params: dict[int, dict[str, tuple[np.ndarray, _Request]]] = field(default_factory=dict)

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
        """Bake the float output ``names`` = (node name, bl_idname, output identifier) of ``material`` for the
        IR float parameter ``param`` of the material ``placeholder``: its texture map ``<param>_map`` where the
        IR has one (roughness, metallic), else the bake's mean over the object's surface (:meth:`apply`)."""
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
                self.baked_params.setdefault(id(req.placeholder), {})[req.param] = (pixels, req)
            else:
                self.baked[id(req.placeholder)] = pixels
            if req.param not in ("", "normal_map") and not _has_map(req.placeholder, req.param):
                continue  # noted with its mean by apply()
            what = {"": "colour", "normal_map": "normal (tangent-space normal map)"}.get(req.param, f"{req.param}_map")
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
                    changes: dict[str, Any] = {}
                    # floats first: a baked emission colour brighter than 1 scales the (baked) strength
                    for p, (px, req) in sorted(params.items(), key=lambda kv: _param(m, kv[0]).kind == "color"):
                        if p == "normal_map":
                            changes[p] = NormalMap(np.clip(px, 0.0, 1.0))
                        elif _has_map(m, p):
                            changes[f"{p}_map"] = TextureMap(np.clip(px, 0.0, 1.0))
                        else:
                            changes.update(self._mean(m, p, px, spec, i if len(mats) > 1 else None, req, changes))
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

    def _mean(
        self, m: Any, param: str, px: np.ndarray, spec: dict[str, Any], slot: int | None, req: Any, done: dict[str, Any]
    ) -> dict[str, Any]:
        """The IR's one value for a baked ``param`` the IR holds as a scalar or a single colour: the bake's mean
        over the surface of the object's faces using material ``slot`` (clipped to the parameter's range; a
        colour in [0, 1], an emission colour brighter than 1 scaling the emission strength); noted."""
        p = _param(m, param)
        colour = p.kind == "color"
        mean = _surface_mean(px[..., :3] if colour else px[..., 0], spec, slot)
        if mean is None:
            self.notes.add(
                f"{req.where}: {param} from a {req.node_type} node baked, but the object has no UVs to "
                "average it over; its default value used"
            )
            return {}
        out: dict[str, Any] = {}
        if colour:
            c, k = rgb01(mean)
            out[param] = (float(c[0]), float(c[1]), float(c[2]), 1.0)
            shown = ", ".join(f"{x:.3g}" for x in np.asarray(mean)[:3])
            if k > 1.0 and param == "emission_color":
                out["emission_strength"] = float(done.get("emission_strength", m.emission_strength)) * k
            elif k > 1.0:
                shown += " normalised to [0, 1]"
        else:
            lo = -np.inf if p.min_value is None else p.min_value
            hi = np.inf if p.max_value is None else p.max_value
            out[param] = float(np.clip(mean, lo, hi))
            shown = f"{out[param]:.4g}"
        self.notes.add(
            f"{req.where}: {param} from a {req.node_type} node baked with Cycles' baker ({self.resolution}x"
            f"{self.resolution}); the IR holds one value for it: the mean over the surface, {shown}, used "
            "(an approximation: the variation across the surface is lost)"
        )
        return out


def _param(m: Any, name: str) -> Any:
    """The declaration of the IR material ``m``'s parameter ``name`` (``normal_map`` included)."""
    return next(q for q in type(m)._params if q.name == name)


def _has_map(m: Any, param: str) -> bool:
    """Whether the IR material ``m`` takes a texture for its float parameter ``param`` (``<param>_map``)."""
    return param != "normal_map" and f"{param}_map" in m.parameter_names()


def _surface_mean(values: np.ndarray, spec: dict[str, Any], slot: int | None) -> Any:
    """Area-weighted mean of a baked (n, n) or (n, n, c) image (row 0 at the top; a float or a (c,) array) over
    a mesh spec's triangles (those of
    material ``slot``): each triangle is split into s x s equal parts (s from its size in texels, the same
    for all, at most 4M samples) read at their UV centroids; None without per-corner or per-vertex UVs."""
    uv, faces, verts = spec.get("uv_map"), np.asarray(spec["faces"]), np.asarray(spec["vertices"], np.float64)
    if uv is None or faces.ndim != 2 or faces.shape[1] != 3:
        return None
    data = np.asarray(uv.data, np.float64)
    corners = data[:, :3] if uv.kind == "faces_uv" else data[faces]  # (M, 3, 2)
    if corners.shape[0] != len(faces):
        return None
    keep = np.ones(len(faces), bool)
    if slot is not None and spec.get("faces_material") is not None:
        keep = np.asarray(spec["faces_material"]) == slot
    tri, corners = verts[faces[keep]], corners[keep]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not len(area) or area.sum() <= 0:
        return None
    n_y, n_x = values.shape[:2]
    edge = np.abs(corners - np.roll(corners, 1, axis=1)).max(axis=(1, 2)) * max(n_x, n_y)  # longest edge, texels
    budget = max(int(np.sqrt(4e6 / len(area))), 1)
    bary = _subdivision_centroids(int(np.clip(np.ceil(edge.max()), 1, min(budget, 256))))
    pts = np.einsum("kb,mbd->mkd", bary, corners)  # (M, K, 2) UVs
    x = np.floor(np.mod(pts[..., 0], 1.0) * n_x).astype(int).clip(0, n_x - 1)
    y = np.floor((1.0 - np.mod(pts[..., 1], 1.0)) * n_y).astype(int).clip(0, n_y - 1)
    per_tri = values[y, x].mean(axis=1)  # (M,) or (M, c)
    mean = np.tensordot(area, per_tri, axes=(0, 0)) / area.sum()
    return float(mean) if np.ndim(mean) == 0 else np.asarray(mean, np.float64)


def _subdivision_centroids(s: int) -> np.ndarray:
    """(s * s, 3) barycentric coordinates of the centroids of a triangle's s x s equal sub-triangles."""
    i, j = np.meshgrid(np.arange(s), np.arange(s), indexing="ij")
    up = (i + j) < s
    down = (i + j) < s - 1
    a = np.concatenate([(i[up] + 1 / 3) / s, (i[down] + 2 / 3) / s])
    b = np.concatenate([(j[up] + 1 / 3) / s, (j[down] + 2 / 3) / s])
    return np.stack([a, b, 1.0 - a - b], axis=1)
