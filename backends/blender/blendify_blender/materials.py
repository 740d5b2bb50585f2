"""IR materials + colour sources -> Cycles node trees.

One bpy material per (renderable, material slot), since the base colour comes from the renderable's
colour source (uniform value, a colour attribute, or an image texture through the ``UVMap`` layer).
Every material also writes its colour input to the ``bf_albedo`` shader AOV (the albedo output).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors

from . import _runtime

__all__ = ["MaterialBuilder", "PRINCIPLED_INPUTS"]

#: IR parameter name -> Principled BSDF input (Blender 4.x/5.x names)
PRINCIPLED_INPUTS: dict[str, str] = {
    "alpha": "Alpha",
    "anisotropic": "Anisotropic",
    "anisotropic_rotation": "Anisotropic Rotation",
    "coat_ior": "Coat IOR",
    "coat_roughness": "Coat Roughness",
    "coat_tint": "Coat Tint",
    "coat_weight": "Coat Weight",
    "diffuse_roughness": "Diffuse Roughness",
    "emission_color": "Emission Color",
    "emission_strength": "Emission Strength",
    "ior": "IOR",
    "metallic": "Metallic",
    "roughness": "Roughness",
    "sheen_weight": "Sheen Weight",
    "sheen_roughness": "Sheen Roughness",
    "sheen_tint": "Sheen Tint",
    "specular_ior": "Specular IOR Level",
    "specular_tint": "Specular Tint",
    "subsurface_anisotropy": "Subsurface Anisotropy",
    "subsurface_radius": "Subsurface Radius",
    "subsurface_scale": "Subsurface Scale",
    "subsurface_weight": "Subsurface Weight",
    "thin_film_ior": "Thin Film IOR",
    "thin_film_thickness": "Thin Film Thickness",
    "transmission_weight": "Transmission Weight",
}
_COLOR_PARAMS = ("coat_tint", "emission_color", "sheen_tint", "specular_tint")
ALBEDO_AOV = "bf_albedo"
UV_LAYER = "UVMap"


class MaterialBuilder:
    """Creates node-tree materials and images, registering every datablock in the given entry."""

    # -- images ------------------------------------------------------------------------------------
    def image_from_array(self, name: str, rgba: np.ndarray, colorspace: str, entry: Any) -> Any:
        """A float image from an (H, W, 4) float32 array with row 0 = top (Blender stores bottom-first).
        One bulk ``foreach_set``; the pixels are not packed (export packs them)."""
        bpy = _runtime.bpy_module()
        h, w = rgba.shape[:2]
        img = entry.add("images", bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=True))
        img.colorspace_settings.name = colorspace
        img.alpha_mode = "STRAIGHT"
        img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
        img.update()
        return img

    def image_from_uint8(self, name: str, data: np.ndarray, colorspace: str, entry: Any) -> Any:
        """A byte image from (H, W, C) uint8 (C = 1, 3, 4; row 0 = top), decoded by Blender with
        ``colorspace`` ("sRGB": the exact IEC curve, as the IR). Bytes round-trip exactly; Cycles keeps
        them as 8-bit textures (4x less memory than float)."""
        bpy = _runtime.bpy_module()
        h, w, c = data.shape
        src = data[::-1]
        px = np.empty((h, w, 4), dtype=np.float32)
        rows = 64  # convert in cache-sized blocks of rows: RGBA bytes -> floats k / 255 (exact round trip)
        t4 = np.empty((rows, w, 4), dtype=np.uint8)
        for r0 in range(0, h, rows):
            n = min(rows, h - r0)
            blk = src[r0 : r0 + n]
            t4[:n, :, :3] = blk if c == 1 else blk[..., :3]
            t4[:n, :, 3] = blk[..., 3] if c == 4 else 255
            np.multiply(t4[:n], np.float32(1.0 / 255.0), out=px[r0 : r0 + n], dtype=np.float32)
        img = entry.add("images", bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=False))
        img.colorspace_settings.name = colorspace
        img.alpha_mode = "STRAIGHT"
        img.pixels.foreach_set(px.ravel())
        img.update()
        return img

    def image_from_file(self, name: str, path: str, colorspace: str, entry: Any) -> Any:
        bpy = _runtime.bpy_module()
        try:
            img = bpy.data.images.load(path, check_existing=False)
        except RuntimeError as exc:
            raise InvalidSceneError(f"texture_path: Blender cannot read {path!r} ({exc})") from exc
        entry.add("images", img)
        img.name = name
        img.colorspace_settings.name = colorspace
        if img.size[0] == 0 or img.size[1] == 0:  # Blender loads lazily: an unreadable file has no size
            raise InvalidSceneError(f"texture_path: Blender cannot read {path!r} as an image")
        return img

    def _data_image(self, name: str, tex: Any, entry: Any) -> Any:
        """A non-colour data texture (roughness/metallic values or normal-map RGB) as a float image."""
        if getattr(tex, "kind", "") == "normal_map":
            img = tex.image()
            rgb = img[..., :3] if img.shape[2] >= 3 else np.repeat(img[..., :1], 3, axis=2)
            v = rgb.astype(np.float32) / 255.0 if rgb.dtype == np.uint8 else rgb.astype(np.float32)
        else:
            v = np.repeat(tex.values()[..., None], 3, axis=2)
        rgba = np.ones(v.shape[:2] + (4,), dtype=np.float32)
        rgba[..., :3] = v
        return self.image_from_array(name, rgba, "Non-Color", entry)

    # -- colour sources ----------------------------------------------------------------------------
    def _color_source(self, nt: Any, name: str, colors: Any, slot: int, entry: Any) -> tuple[Any, Any]:
        """(colour, alpha): each a node output socket or a constant (4-tuple / float)."""
        if isinstance(colors, UniformColors):
            rgba = colors.linear_rgba
            return tuple(float(x) for x in rgba), float(rgba[3])
        if isinstance(colors, VertexColors):
            node = nt.nodes.new("ShaderNodeAttribute")
            node.attribute_type = "GEOMETRY"
            node.attribute_name = f"bf_color_{slot}"
            return node.outputs["Color"], (node.outputs["Alpha"] if colors.has_alpha else 1.0)
        if isinstance(colors, TextureColors):
            t0 = time.perf_counter()
            if colors.texture.dtype == np.uint8:
                cs = "sRGB" if colors.color_space == "srgb" else "Linear Rec.709"
                img = self.image_from_uint8(f"{name}_tex", colors.texture, cs, entry)
            else:
                img = self.image_from_array(f"{name}_tex", colors.linear_rgba_image(), "Linear Rec.709", entry)
            entry.timings["texture_upload"] = entry.timings.get("texture_upload", 0.0) + time.perf_counter() - t0
        elif isinstance(colors, FileTextureColors):
            cs = "sRGB" if colors.color_space == "srgb" else "Linear Rec.709"
            img = self.image_from_file(f"{name}_tex", colors.texture_path, cs, entry)
        else:  # pragma: no cover - the IR has no other colour sources
            raise InvalidSceneError(f"colors: unsupported colour source {type(colors).__name__}")
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Closest" if colors.interpolation == "closest" else "Linear"
        tex.extension = "REPEAT"
        uv = nt.nodes.new("ShaderNodeUVMap")
        uv.uv_map = UV_LAYER
        nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
        return tex.outputs["Color"], (tex.outputs["Alpha"] if colors.has_alpha else 1.0)

    @staticmethod
    def _feed(nt: Any, value: Any, socket: Any) -> None:
        if hasattr(value, "links") or hasattr(value, "node"):
            nt.links.new(value, socket)
        else:
            socket.default_value = value

    def _alpha(self, nt: Any, material_alpha: float, color_alpha: Any) -> Any:
        if isinstance(color_alpha, float):
            return float(material_alpha) * color_alpha
        if material_alpha == 1.0:
            return color_alpha
        mul = nt.nodes.new("ShaderNodeMath")
        mul.operation = "MULTIPLY"
        mul.inputs[0].default_value = float(material_alpha)
        nt.links.new(color_alpha, mul.inputs[1])
        return mul.outputs[0]

    def _uv_texture(self, nt: Any, img: Any) -> Any:
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Linear"
        uv = nt.nodes.new("ShaderNodeUVMap")
        uv.uv_map = UV_LAYER
        nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
        return tex

    # -- materials ---------------------------------------------------------------------------------
    def build(
        self,
        name: str,
        material: Any,
        colors: Any,
        slot: int,
        entry: Any,
        emission_from_color: float = 0.0,
    ) -> Any:
        """A bpy material for IR ``material`` coloured by ``colors``. ``emission_from_color`` > 0 makes
        the surface emit its own colour with that strength (point-cloud emission)."""
        bpy = _runtime.bpy_module()
        mat = entry.add("materials", bpy.data.materials.new(name))
        mat.use_backface_culling = False
        nt = mat.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        out.target = "ALL"
        color, color_alpha = self._color_source(nt, name, colors, slot, entry)
        v = material.parameters()
        alpha = self._alpha(nt, float(v.get("alpha", 1.0)), color_alpha)
        if material.kind == "glossy":
            bsdf = nt.nodes.new("ShaderNodeBsdfGlossy")
            bsdf.distribution = v["distribution"]
            bsdf.inputs["Roughness"].default_value = float(v["roughness"])
            self._feed(nt, color, bsdf.inputs["Color"])
            surface = bsdf.outputs["BSDF"]
            if not (isinstance(alpha, float) and alpha >= 1.0):
                transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
                mix = nt.nodes.new("ShaderNodeMixShader")
                self._feed(nt, alpha, mix.inputs["Factor"])
                nt.links.new(transparent.outputs[0], mix.inputs[1])
                nt.links.new(surface, mix.inputs[2])
                surface = mix.outputs[0]
            if emission_from_color > 0:
                emit = nt.nodes.new("ShaderNodeEmission")
                self._feed(nt, color, emit.inputs["Color"])
                emit.inputs["Strength"].default_value = float(emission_from_color)
                add = nt.nodes.new("ShaderNodeAddShader")
                nt.links.new(surface, add.inputs[0])
                nt.links.new(emit.outputs[0], add.inputs[1])
                surface = add.outputs[0]
        else:
            bsdf = self._principled(nt, name, material, v, color, alpha, entry, emission_from_color)
            surface = bsdf.outputs["BSDF"]
        albedo = color
        if material.has_wireframe:
            wire = nt.nodes.new("ShaderNodeWireframe")
            wire.use_pixel_size = False
            wire.inputs["Size"].default_value = float(v["wireframe_thickness"])
            wire_color = tuple(float(x) for x in material.linear("wireframe_color"))
            wbsdf = self._principled(nt, name, material, v, wire_color, alpha, entry, 0.0)
            mix = nt.nodes.new("ShaderNodeMixShader")
            nt.links.new(wire.outputs["Factor"], mix.inputs["Factor"])
            nt.links.new(surface, mix.inputs[1])
            nt.links.new(wbsdf.outputs["BSDF"], mix.inputs[2])
            surface = mix.outputs[0]
            cmix = nt.nodes.new("ShaderNodeMix")
            cmix.data_type = "RGBA"
            # ShaderNodeMix sockets by type: 0 float factor, 6/7 colour A/B, output 2 colour
            nt.links.new(wire.outputs["Factor"], cmix.inputs[0])
            self._feed(nt, color, cmix.inputs[6])
            cmix.inputs[7].default_value = wire_color
            albedo = cmix.outputs[2]
        nt.links.new(surface, out.inputs["Surface"])
        aov = nt.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = ALBEDO_AOV
        self._feed(nt, albedo, aov.inputs["Color"])
        return mat

    def _principled(
        self,
        nt: Any,
        name: str,
        material: Any,
        v: dict[str, Any],
        color: Any,
        alpha: Any,
        entry: Any,
        emission_from_color: float,
    ) -> Any:
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
        for key, socket in PRINCIPLED_INPUTS.items():
            if key not in v or key == "alpha":
                continue
            if key in _COLOR_PARAMS:
                bsdf.inputs[socket].default_value = tuple(float(x) for x in material.linear(key))
            elif key == "subsurface_radius":
                bsdf.inputs[socket].default_value = tuple(float(x) for x in v[key])
            else:
                bsdf.inputs[socket].default_value = float(v[key])
        self._feed(nt, color, bsdf.inputs["Base Color"])
        self._feed(nt, alpha, bsdf.inputs["Alpha"])
        if emission_from_color > 0:
            self._feed(nt, color, bsdf.inputs["Emission Color"])
            bsdf.inputs["Emission Strength"].default_value = float(emission_from_color)
        for key, socket in (("roughness_map", "Roughness"), ("metallic_map", "Metallic")):
            tex_map = v.get(key)
            if tex_map is not None:
                img = self._data_image(f"{name}_{key}", tex_map, entry)
                tex = self._uv_texture(nt, img)
                nt.links.new(tex.outputs["Color"], bsdf.inputs[socket])
        nmap = v.get("normal_map")
        if nmap is not None:
            img = self._data_image(f"{name}_normal", nmap, entry)
            tex = self._uv_texture(nt, img)
            node = nt.nodes.new("ShaderNodeNormalMap")
            node.space = "TANGENT"
            node.uv_map = UV_LAYER
            node.inputs["Strength"].default_value = float(nmap.strength)
            nt.links.new(tex.outputs["Color"], node.inputs["Color"])
            nt.links.new(node.outputs["Normal"], bsdf.inputs["Normal"])
        return bsdf
