"""Material node trees of a .blend -> IR materials and colour-source descriptions.

- Principled BSDF (and Diffuse / Glossy / Emission shaders, a Mix with a Transparent BSDF = alpha, a Mix
  with a Wireframe factor = wireframe material) -> PrincipledBSDFMaterial / GlossyBSDFMaterial /
  PrincipledBSDFWireframeMaterial with every mapped parameter (``color_space="linear"``);
- the Base Color's source: a uniform value, a colour attribute (Color Attribute / Attribute node, any
  domain and storage) or an image texture (with its UV map); :mod:`.geometry` turns the description
  into the IR colour source of each mesh;
- texture-driven Roughness / Metallic -> ``roughness_map`` / ``metallic_map``, a tangent-space Normal Map
  node fed by an image -> ``normal_map`` (with a baker, any other shading normal: Bump, procedural or
  object/world-space Normal Map -> a baked tangent-space ``normal_map``);
- with a baker (:mod:`.bake`), every other float or colour input driven by nodes (procedural Roughness /
  Metallic, IOR, Coat Weight, Transmission, Emission Strength, Alpha, Emission Color, Coat / Sheen / Specular
  Tint, ...) is baked per object: into the IR's texture map where it has one, else the bake's surface mean
  (named in the warning).

Anything else that drives a socket (procedural nodes, volumes, displacement) is noted and its default
value used. :func:`link_from` (the node feeding a socket, through reroutes) is shared with the light and
world parsers.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes, rgb01
from blendify_blender.blendfile.images import ImageReader
from blendify_core.ir.colors import NormalMap, TextureMap
from blendify_core.ir.materials import GlossyBSDFMaterial, PrincipledBSDFMaterial, PrincipledBSDFWireframeMaterial

__all__ = ["MaterialReader", "link_from"]

#: Principled BSDF float inputs -> IR parameter names
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
#: Principled BSDF colour inputs (besides Base Color) -> IR parameter names
_COLOR_INPUTS = {
    "Specular Tint": "specular_tint",
    "Coat Tint": "coat_tint",
    "Sheen Tint": "sheen_tint",
    "Emission Color": "emission_color",
}
#: Principled BSDF inputs the IR has no parameter for (noted when driven by nodes)
_IGNORED_INPUTS = ("Weight", "Tangent", "Coat Normal", "Subsurface IOR")
#: _normal_map's answer for a normal the baker makes into a normal map per object
_BAKE_NORMAL = object()
#: the colour description of a material without a usable colour source
_DEFAULT_GREY = {"kind": "uniform", "rgba": (0.8, 0.8, 0.8, 1.0)}


def link_from(socket: Any) -> tuple[Any, Any] | None:
    """(node, output socket) feeding ``socket`` through reroutes, or None (unlinked, muted, dangling)."""
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


def _param_ranges() -> dict[str, tuple[float | None, float | None]]:
    return {p.name: (p.min_value, p.max_value) for p in PrincipledBSDFMaterial._params if p.kind == "float"}


class MaterialReader:
    """Parses the materials of one .blend (each once) into (IR material, colour description).

    A colour description is a dict: ``{"kind": "uniform", "rgba"}``, ``{"kind": "attribute", "name",
    "node"}`` or ``{"kind": "texture", "image", "uv", "channel", "interpolation", "node"}``, plus
    ``"opaque"`` (the source's alpha is not used) and ``"emission_from_color"`` (the surface emits its
    base colour with this strength)."""

    def __init__(self, images: ImageReader, notes: Notes, baker: Any = None) -> None:
        self.images = images
        self.notes = notes
        #: a blendfile.bake.Baker: procedural colours become "bake" descriptions instead of their default value
        self.baker = baker
        #: (IR parameter, (node name, bl_idname, output identifier)) of the Principled float inputs driven by
        #: nodes, baked per object: into ``<parameter>_map`` where the IR has one, else the bake's mean
        self._maps_to_bake: list[tuple[str, tuple[str, str, str]]] = []
        self._ranges = _param_ranges()
        self._cache: dict[int, tuple[Any, dict[str, Any]]] = {}

    def cached(self, mat: Any, where: str) -> tuple[Any, dict[str, Any]]:
        """:meth:`material`, parsed once per Blender material (notes name the first user, ``where``)."""
        key = mat.as_pointer() if mat is not None else 0
        if key not in self._cache:
            parsed = self.material(mat, where)
            if parsed[1].get("kind") == "bake" or parsed[1].get("bake_maps"):
                parsed[1]["material"] = mat
            self._cache[key] = parsed
        return self._cache[key]

    # -- texture and colour sources --------------------------------------------------------------
    def _uv_layer_name(self, image_node: Any, where: str) -> tuple[str, np.ndarray | None]:
        """(UV layer: '' = the mesh's render UV layer, or a name; 2x3 affine UV transform of a Mapping node
        or None). Other texture coordinates are noted and replaced by the UV map."""
        vec = image_node.inputs.get("Vector")
        src = link_from(vec) if vec is not None else None
        if src is None:
            return "", None
        node, sock = src
        transform = None
        if node.type == "MAPPING":
            transform = self._mapping(node, where)
            inner = link_from(node.inputs["Vector"])
            if inner is None:
                self.notes.add(f"{where}: Mapping node {node.name!r} without an input vector, read as the UV map")
                return "", transform
            node, sock = inner
        if node.type == "UVMAP":
            return node.uv_map, transform
        if node.type == "TEX_COORD" and sock.name == "UV":
            return "", transform
        self.notes.add(f"{where}: texture coordinates from a {node.bl_idname} node replaced by the UV map")
        return "", transform

    def _mapping(self, node: Any, where: str) -> np.ndarray | None:
        """A Mapping node on UVs as a 2x3 affine transform of (u, v) (rotation about Z only; a driven or
        out-of-plane input is noted and left out)."""
        kind = node.vector_type
        if kind not in ("POINT", "TEXTURE", "VECTOR"):
            self.notes.add(f"{where}: Mapping node {node.name!r} of type {kind} not applied to the UVs")
            return None
        vals = {}
        for name in ("Location", "Rotation", "Scale"):
            sock = node.inputs.get(name)
            if sock is None or not sock.enabled:
                vals[name] = np.array([0.0, 0.0, 0.0]) if name != "Scale" else np.ones(3)
                continue
            if sock.is_linked:
                self.notes.add(f"{where}: Mapping node {node.name!r} input {name!r} driven by nodes, default used")
            vals[name] = np.array(sock.default_value, dtype=np.float64)
        loc, rot, scale = vals["Location"], vals["Rotation"], vals["Scale"]
        if abs(rot[0]) > 1e-9 or abs(rot[1]) > 1e-9 or abs(loc[2]) > 1e-9:
            self.notes.add(f"{where}: Mapping node {node.name!r} out-of-plane rotation/location left out")
        c, sn = math.cos(rot[2]), math.sin(rot[2])
        a = np.array([[c, -sn], [sn, c]]) @ np.diag(scale[:2])
        b = loc[:2] if kind != "VECTOR" else np.zeros(2)
        if kind == "TEXTURE":  # the inverse of POINT
            if abs(np.linalg.det(a)) < 1e-12:
                self.notes.add(f"{where}: Mapping node {node.name!r} with a zero scale not applied")
                return None
            a = np.linalg.inv(a)
            b = -a @ loc[:2]
        return np.hstack([a, b[:, None]])

    def texture_input(self, socket: Any, where: str, what: str) -> dict[str, Any] | None:
        """An Image Texture feeding ``socket``: {'image': source, 'uv': layer name, 'channel', ...}."""
        src = link_from(socket)
        if src is None:
            return None
        node, out = src
        if node.type != "TEX_IMAGE":
            self.notes.add(
                f"{where}: {what} comes from a {node.bl_idname} node (procedural), used its default value instead"
            )
            return None
        if node.image is None:
            self.notes.add(f"{where}: {what} image node has no image")
            return None
        if node.projection != "FLAT":
            self.notes.add(f"{where}: {what} image projection {node.projection} read as FLAT")
        img = self.images.source(node.image, where)
        if img is None:
            return None
        if node.extension != "REPEAT":
            self.notes.add(f"{where}: {what} image extension {node.extension} read as REPEAT")
        if node.interpolation not in ("Linear", "Closest"):
            self.notes.add(f"{where}: {what} image interpolation {node.interpolation} read as Linear")
        uv, transform = self._uv_layer_name(node, where)
        return {
            "image": img,
            "uv": uv,
            "uv_transform": transform,
            "channel": 3 if out.name == "Alpha" else 0,
            "interpolation": "closest" if node.interpolation == "Closest" else "linear",
        }

    def _color_source(self, socket: Any, where: str) -> dict[str, Any]:
        """How a colour input is driven: uniform value, a colour attribute or an image texture."""
        src = link_from(socket)
        default = tuple(socket.default_value)
        if src is None:
            return {"kind": "uniform", "rgba": default}
        node, out = src
        if node.type == "TEX_IMAGE":
            tex = self.texture_input(socket, where, socket.name)
            if tex is not None:
                return {"kind": "texture", "node": node, **tex}
        elif node.type == "VERTEX_COLOR":
            return {"kind": "attribute", "name": node.layer_name, "node": node}
        elif node.type == "ATTRIBUTE" and node.attribute_type == "GEOMETRY" and out.name == "Color":
            return {"kind": "attribute", "name": node.attribute_name, "node": node}
        elif node.type == "RGB":
            return {"kind": "uniform", "rgba": tuple(out.default_value)}
        elif self.baker is not None:  # procedural: baked per object by blendfile.bake (default value until then)
            return {"kind": "bake", "rgba": default, "node": node, "socket": out, "where": f"{where}: {socket.name}"}
        else:
            self.notes.add(
                f"{where}: {socket.name} comes from a {node.bl_idname} node (procedural), used its default value"
            )
        return {"kind": "uniform", "rgba": default}

    # -- materials -------------------------------------------------------------------------------
    def material(self, mat: Any, where: str) -> tuple[Any, dict[str, Any]]:
        """(IR material, colour source description) of a Blender material (or None)."""
        if mat is None:
            return PrincipledBSDFMaterial(color_space="linear"), dict(_DEFAULT_GREY)
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
            self.notes.add(f"{where}: no Material Output node, rendered as default grey")
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        out = active[0]
        for extra in ("Volume", "Displacement", "Thickness"):
            sock = out.inputs.get(extra)
            if sock is not None and sock.is_linked:
                self.notes.add(f"{where}: {extra.lower()} shader not parsed")
        src = link_from(out.inputs["Surface"])
        if src is None:
            self.notes.add(f"{where}: nothing connected to the surface output, rendered as default grey")
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        parsed = self._shader(src[0], where)
        if parsed is None:
            self.notes.add(
                f"{where}: surface shader {src[0].bl_idname} (node tree) cannot be parsed, "
                "rendered as a Principled BSDF with the viewport colour"
            )
            return PrincipledBSDFMaterial(color_space="linear"), fallback
        return parsed

    def _shader(self, node: Any, where: str) -> tuple[Any, dict[str, Any]] | None:
        """(IR material, colour description) of a shader node, or None when it cannot be parsed."""
        if node.type == "BSDF_PRINCIPLED":
            return self._principled(node, where)
        if node.type == "BSDF_DIFFUSE":
            col = self._color_source(node.inputs["Color"], where)
            self._ignore_links(node, ("Color",), where)
            # Blender's Diffuse BSDF roughness is the Oren-Nayar roughness of the Principled diffuse lobe
            rough = self._clip("diffuse_roughness", node.inputs["Roughness"].default_value, where)
            m = PrincipledBSDFMaterial(color_space="linear", roughness=1.0, specular_ior=0.0, diffuse_roughness=rough)
            return m, col
        if node.type == "BSDF_TRANSPARENT":
            self._ignore_links(node, (), where)
            self._transparent_tint(node, where)
            return PrincipledBSDFMaterial(color_space="linear", alpha=0.0), dict(_DEFAULT_GREY)
        if node.type == "BSDF_GLOSSY":
            col = self._color_source(node.inputs["Color"], where)
            self._ignore_links(node, ("Color",), where)
            dist = (
                node.distribution
                if node.distribution in ("GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY", "MULTI_GGX")
                else "GGX"
            )
            rough = float(np.clip(node.inputs["Roughness"].default_value, 0.0, 1.0))
            aniso = node.inputs.get("Anisotropy")
            if aniso is not None and (aniso.is_linked or abs(float(aniso.default_value)) > 1e-6):
                self.notes.add(f"{where}: {node.name} anisotropy left out (the IR's Glossy BSDF is isotropic)")
            return GlossyBSDFMaterial(roughness=rough, distribution=dist, color_space="linear"), col
        if node.type in ("BSDF_GLASS", "BSDF_REFRACTION"):
            return self._glass(node, where)
        if node.type == "ADD_SHADER":
            return self._add_shader(node, where)
        if node.type == "EMISSION":
            self._ignore_links(node, (), where)
            c, k = rgb01(node.inputs["Color"].default_value)
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
        a = link_from(node.inputs[1])
        b = link_from(node.inputs[2])
        if a is None or b is None:
            return None
        fsrc = link_from(node.inputs[0])
        if fsrc is not None and fsrc[0].type == "WIREFRAME" and a[0].type == b[0].type == "BSDF_PRINCIPLED":
            return self._wireframe(fsrc[0], a[0], b[0], where)
        if a[0].type == "BSDF_TRANSPARENT" or b[0].type == "BSDF_TRANSPARENT":
            return self._transparent(node, a[0], b[0], fsrc, where)
        # any other mix: the IR has no mixed material -- the shader with the larger weight, said so
        f = 0.5 if fsrc is not None else float(np.clip(node.inputs[0].default_value, 0.0, 1.0))
        first, second = (a[0], b[0]) if f <= 0.5 else (b[0], a[0])
        parsed = self._shader(first, where) or self._shader(second, where)
        if parsed is None:
            return None
        factor = "driven by nodes" if fsrc is not None else f"{f:g}"
        self.notes.add(
            f"{where}: {node.name} (factor {factor}) of {a[0].name} and {b[0].name} approximated by one of them "
            "(the IR has no mixed material)"
        )
        return parsed

    def _glass(self, node: Any, where: str) -> tuple[Any, dict[str, Any]]:
        """Glass / Refraction BSDF -> Principled with full transmission (its roughness, IOR, distribution)."""
        col = self._color_source(node.inputs["Color"], where)
        self._ignore_links(node, ("Color",), where)
        if node.type == "BSDF_REFRACTION":
            self.notes.add(f"{where}: {node.name} (refraction only) approximated by glass (with its reflection)")
        dist = node.distribution
        if dist not in ("GGX", "MULTI_GGX"):
            self.notes.add(f"{where}: {node.name} distribution {dist} read as GGX")
            dist = "GGX"
        if col["kind"] != "uniform" or min(col["rgba"][:3]) < 0.999:
            self.notes.add(
                f"{where}: {node.name} colour tints the transmission only in the IR (also the reflection in Blender)"
            )
        m = PrincipledBSDFMaterial(
            color_space="linear",
            transmission_weight=1.0,
            metallic=0.0,
            roughness=self._clip("roughness", node.inputs["Roughness"].default_value, where),
            ior=self._clip("ior", node.inputs["IOR"].default_value, where),
            specular_ior=0.5,
            specular_tint=(1.0, 1.0, 1.0, 1.0),
            distribution=dist,
        )
        return m, col

    def _add_shader(self, node: Any, where: str) -> tuple[Any, dict[str, Any]] | None:
        """Add Shader: a shader plus an Emission of a uniform colour -> the shader with that emission; any
        other sum -> the first shader that parses, said so."""
        srcs = [link_from(node.inputs[0]), link_from(node.inputs[1])]
        nodes = [s_[0] for s_ in srcs if s_ is not None]
        emission = [n for n in nodes if n.type == "EMISSION" and not n.inputs["Color"].is_linked]
        others = [n for n in nodes if n not in emission[:1]]
        if emission and len(others) == 1:
            parsed = self._shader(others[0], where)
            if parsed is not None and "emission_strength" in parsed[0].parameter_names():
                m, col = parsed
                enode = emission[0]
                self._ignore_links(enode, ("Color",), where)
                rgb = np.asarray(enode.inputs["Color"].default_value[:3], dtype=np.float64)
                rgb = rgb * max(float(enode.inputs["Strength"].default_value), 0.0)
                rgb = rgb + np.asarray(m.linear("emission_color")[:3]) * float(m.emission_strength)
                c, k = rgb01(rgb)
                if float(m.get("coat_weight")) > 0:
                    self.notes.add(f"{where}: {node.name}: the added emission is under the coat in the IR")
                return m.copy(
                    emission_color=(*(float(x) for x in c), 1.0), emission_strength=k if c.max() > 0 else 0.0
                ), col
        # the surface shader first: an emission alone would replace the surface by a light
        for n in sorted(nodes, key=lambda x: x.type == "EMISSION"):
            parsed = self._shader(n, where)
            if parsed is not None:
                names = " + ".join(x.name for x in nodes)
                self.notes.add(f"{where}: {node.name} ({names}) approximated by {n.name} alone")
                return parsed
        return None

    def _wireframe(self, wire: Any, surface: Any, lines: Any, where: str) -> tuple[Any, dict[str, Any]]:
        """Mix(Wireframe factor, surface Principled, wire Principled) -> PrincipledBSDFWireframeMaterial."""
        if wire.use_pixel_size:
            self.notes.add(f"{where}: wireframe size in pixels read as world units")
        base, col = self._principled(surface, where)
        wsock = lines.inputs["Base Color"]
        if wsock.is_linked:
            self.notes.add(f"{where}: wireframe colour driven by nodes, used its default value")
        wc, _k = rgb01(wsock.default_value)
        m = PrincipledBSDFWireframeMaterial(
            wireframe_thickness=max(float(wire.inputs["Size"].default_value), 0.0),
            wireframe_color=(float(wc[0]), float(wc[1]), float(wc[2]), 1.0),
            color_space="linear",
            **{n: getattr(base, n) for n in base.parameter_names()},
        )
        return m, col

    def _transparent(
        self, node: Any, a: Any, b: Any, fsrc: tuple[Any, Any] | None, where: str
    ) -> tuple[Any, dict[str, Any]] | None:
        """Mix(factor, a, b) with a Transparent BSDF on one side -> the other shader with an alpha."""
        other = b if a.type == "BSDF_TRANSPARENT" else a
        self._transparent_tint(a if other is b else b, where)
        parsed = self._shader(other, where)
        if parsed is None:
            return None
        m, col = parsed
        if fsrc is None:
            f = float(np.clip(node.inputs[0].default_value, 0.0, 1.0))
            alpha = f if a.type == "BSDF_TRANSPARENT" else 1.0 - f
        elif fsrc[1].name == "Alpha" and col.get("node") == fsrc[0] and a.type == "BSDF_TRANSPARENT":
            alpha = 1.0  # the colour source's own alpha
        else:
            self.notes.add(f"{where}: transparency factor driven by nodes, read as opaque")
            alpha = 1.0
        if "alpha" in m.parameter_names():
            m = m.copy(alpha=float(m.alpha) * alpha)
        return m, col

    def _transparent_tint(self, node: Any, where: str) -> None:
        """Note a Transparent BSDF that is not white: the IR's alpha lets light through untinted."""
        sock = node.inputs["Color"]
        rgb = tuple(float(x) for x in sock.default_value[:3])
        if sock.is_linked:
            self.notes.add(
                f"{where}: {node.name} colour is driven by nodes; read as untinted transparency (the IR's alpha)"
            )
        elif min(rgb) < 0.999:
            tint = ", ".join(f"{x:.3g}" for x in rgb)
            self.notes.add(
                f"{where}: {node.name} is tinted ({tint}); approximated by untinted transparency (the IR's alpha "
                "has no colour)"
            )

    def _ignore_links(self, node: Any, handled: tuple[str, ...], where: str) -> None:
        for sock in node.inputs:
            if sock.name not in handled and sock.enabled and sock.is_linked:
                self.notes.add(f"{where}: {node.name} input {sock.name!r} is driven by nodes, used its default value")

    def _clip(self, name: str, value: float, where: str) -> float:
        """``value`` clipped to the IR parameter's range (noted when it changes; non-finite -> 0)."""
        lo, hi = self._ranges.get(name, (None, None))
        v = float(value)
        if not math.isfinite(v):
            self.notes.add(f"{where}: {name} = {v} replaced by 0")
            return 0.0
        c = v
        if lo is not None and c < lo:
            c = lo
        if hi is not None and c > hi:
            c = hi
        if c != v and abs(c - v) > 1e-6:
            self.notes.add(f"{where}: {name} = {v:g} clipped to {c:g}")
        return c

    # -- Principled BSDF -------------------------------------------------------------------------
    def _principled(self, node: Any, where: str) -> tuple[Any, dict[str, Any]]:
        inputs = {s.name: s for s in node.inputs}
        params: dict[str, Any] = {}
        self._maps_to_bake = []
        self._principled_floats(node, inputs, params, where)
        emission_from_color = self._principled_colors(inputs, params, where)
        sock = inputs.get("Subsurface Radius")
        if sock is not None:
            params["subsurface_radius"] = tuple(max(float(x), 0.0) for x in sock.default_value)
        if node.distribution in ("GGX", "MULTI_GGX"):
            params["distribution"] = node.distribution
        else:  # pragma: no cover - Blender 5 offers only these two
            self.notes.add(f"{where}: Principled distribution {node.distribution} read as MULTI_GGX")
        nm = self._normal_map(inputs.get("Normal"), where)
        bake_normal = nm is _BAKE_NORMAL
        if nm is not None and not bake_normal:
            params["normal_map"] = nm
        for name in _IGNORED_INPUTS:
            s = inputs.get(name)
            if s is not None and s.enabled and s.is_linked:
                self.notes.add(f"{where}: Principled input {name!r} not parsed")
        colors = self._color_source(inputs["Base Color"], where)
        if bake_normal:
            src = link_from(inputs["Normal"])
            colors["bake_normal"] = src[0].bl_idname if src is not None else "node"
            if src is not None and src[0].type == "NORMAL_MAP" and src[0].space != "TANGENT":
                colors["bake_normal"] += f" ({src[0].space.lower().replace('blender_', 'Blender ')}-space)"
        if self._maps_to_bake:
            colors["bake_maps"] = list(self._maps_to_bake)
        if emission_from_color > 0:
            colors["emission_from_color"] = emission_from_color
        if colors["kind"] in ("texture", "attribute") and self._alpha_value(node) is None:
            colors["opaque"] = True  # Blender ignores the colour source's alpha: the IR must too
        return PrincipledBSDFMaterial(color_space="linear", **params), colors

    def _principled_floats(self, node: Any, inputs: dict[str, Any], params: dict[str, Any], where: str) -> None:
        """The float inputs (their default values, clipped) and the Roughness / Metallic texture maps."""
        for bl_name, ir_name in _FLOAT_INPUTS.items():
            sock = inputs.get(bl_name)
            if sock is None:
                continue
            src = link_from(sock) if sock.is_linked else None
            mapped = f"{ir_name}_map" in PrincipledBSDFMaterial.parameter_names()
            alpha_of_colour = ir_name == "alpha" and src is not None and self._alpha_value(node) is not None
            if src is not None and self.baker is not None and not alpha_of_colour:
                if not (mapped and src[0].type == "TEX_IMAGE"):  # baked per object (blendfile.bake): a map, or
                    names = (str(src[0].name), str(src[0].bl_idname), str(src[1].identifier))  # its mean
                    self._maps_to_bake.append((ir_name, names))
                    params[ir_name] = self._clip(ir_name, sock.default_value, where)
                    continue
            if sock.is_linked and mapped:
                tex = self.texture_input(sock, where, bl_name)
                if tex is not None:
                    params[f"{ir_name}_map"] = self._texture_map(tex, TextureMap, where=where)
            elif ir_name == "alpha" and sock.is_linked:
                alpha = self._alpha_value(node)
                if alpha is None:
                    self.notes.add(f"{where}: Principled input 'Alpha' is driven by nodes, used its default value")
                else:
                    params["alpha"] = self._clip("alpha", alpha, where)
                    continue
            elif sock.is_linked:
                self.notes.add(f"{where}: Principled input {bl_name!r} is driven by nodes, used its default value")
            params[ir_name] = self._clip(ir_name, sock.default_value, where)

    def _principled_colors(self, inputs: dict[str, Any], params: dict[str, Any], where: str) -> float:
        """The colour inputs besides Base Color (normalised to [0, 1], an emission colour > 1 scaling the
        strength); returns the emission strength when the surface emits its base colour, else 0."""
        base_src = link_from(inputs["Base Color"])
        emission_from_color = 0.0
        for bl_name, ir_name in _COLOR_INPUTS.items():
            sock = inputs.get(bl_name)
            if sock is None:
                continue
            if ir_name == "emission_color" and sock.is_linked and base_src is not None:
                esrc = link_from(sock)
                if esrc is not None and esrc[0] == base_src[0] and esrc[1].name == base_src[1].name:
                    # the surface emits its own colour (point clouds' particle_emission_strength)
                    emission_from_color = float(params.get("emission_strength", 0.0))
                    params["emission_strength"] = 0.0
                    continue
            src = link_from(sock) if sock.is_linked else None
            if src is not None and self.baker is not None:  # baked per object (blendfile.bake): its mean colour
                self._maps_to_bake.append((ir_name, (str(src[0].name), str(src[0].bl_idname), str(src[1].identifier))))
            elif sock.is_linked:
                self.notes.add(f"{where}: Principled input {bl_name!r} is driven by nodes, used its default value")
            c, k = rgb01(sock.default_value)
            if k > 1.0:
                if ir_name == "emission_color":
                    params["emission_strength"] = params.get("emission_strength", 0.0) * k
                else:
                    self.notes.add(f"{where}: {bl_name} > 1 normalised to [0, 1]")
            params[ir_name] = (float(c[0]), float(c[1]), float(c[2]), 1.0)
        return emission_from_color

    def _normal_map(self, normal: Any, where: str) -> Any:
        """A tangent-space Normal Map node fed by an image on the Normal input -> IR NormalMap; any other
        shading normal -> _BAKE_NORMAL with a baker (a Bump, a procedural or object/world-space Normal Map:
        baked per object into a tangent-space normal map), else None (noted)."""
        if normal is None or not normal.is_linked:
            return None
        src = link_from(normal)
        if src is not None and src[0].type == "NORMAL_MAP":
            nnode = src[0]
            if nnode.space != "TANGENT":
                if self.baker is not None:  # object / world space: the shading normal baked in tangent space
                    return _BAKE_NORMAL
                self.notes.add(
                    f"{where}: {nnode.space.lower()}-space normal map not parsed (bake_resolution=None; the IR "
                    "holds tangent-space normal maps)"
                )
                return None
            csrc = link_from(nnode.inputs["Color"])
            if self.baker is not None and csrc is not None and csrc[0].type != "TEX_IMAGE":
                return _BAKE_NORMAL  # a procedural normal map: baked per object (blendfile.bake)
            tex = self.texture_input(nnode.inputs["Color"], where, "Normal Map color")
            if tex is None:
                return None
            strength = float(nnode.inputs["Strength"].default_value)
            return self._texture_map(tex, NormalMap, where=where, strength=strength)
        if src is not None and self.baker is not None:
            return _BAKE_NORMAL  # a Bump node (or other): the shading normal baked per object
        if src is not None:
            self.notes.add(f"{where}: Normal input from a {src[0].bl_idname} node not parsed")
        return None

    def _alpha_value(self, node: Any) -> float | None:
        """Material alpha when Alpha is the colour source's own alpha (the Alpha output of the node that
        feeds Base Color), optionally multiplied by a constant (Math MULTIPLY); else None."""
        base = link_from(node.inputs["Base Color"])
        a = link_from(node.inputs["Alpha"])
        if base is None or a is None:
            return None

        def is_colour_alpha(src: tuple[Any, Any] | None) -> bool:
            return src is not None and src[0] == base[0] and src[1].name == "Alpha"

        if is_colour_alpha(a):
            return 1.0
        mnode = a[0]
        if mnode.type == "MATH" and mnode.operation == "MULTIPLY":
            i0, i1 = mnode.inputs[0], mnode.inputs[1]
            if is_colour_alpha(link_from(i1)) and not i0.is_linked:
                return float(i0.default_value)
            if is_colour_alpha(link_from(i0)) and not i1.is_linked:
                return float(i1.default_value)
        return None

    def _texture_map(self, tex: dict[str, Any], cls: Any, where: str, **kw: Any) -> Any:
        if tex.get("uv_transform") is not None:
            self.notes.add(f"{where}: a {cls.__name__} reads the mesh's UV map as it is: its Mapping node left out")
        kind, data, _cs = tex["image"]
        if cls is NormalMap:
            return cls(data, **kw)
        return (
            cls(data, channel=tex["channel"])
            if kind == "file"
            else cls(data, channel=min(tex["channel"], data.shape[2] - 1))
        )
