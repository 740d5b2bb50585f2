"""Cycles node trees for the translator's material and colour-source handlers (:mod:`.translate`).

One bpy material per (renderable, material slot), since the base colour comes from the renderable's
colour source (uniform value, a colour attribute, or an image texture through the ``UVMap`` layer);
materials with a uniform colour are shared by every object using the same (material, colour). Every
material also writes its colour input to the ``bf_albedo`` shader AOV (the albedo output) and its shading
normal to the ``bf_normal`` AOV (the normal output): the interpolated normal (Geometry node, turned to the
viewer on back faces), or the normal map's. Cycles' own Normal pass is the closure-weighted mean of the
BSDFs' normals, and the Principled BSDF's glossy layers bend theirs where the interpolated normal faces away
from the camera (grazing views of coarse smooth meshes, ``ensure_valid_specular_reflection``): the pass would
then depend on the material and differ from the IR's normal, which the other backends report.

The builder knows node trees, not IR types: the translator's handlers pick the pieces (a colour source's
nodes, a Principled or Glossy BSDF, a wireframe overlay) and read the IR's attributes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError

from .session import bpy_module

__all__ = ["MaterialBuilder", "PRINCIPLED_INPUTS", "ALBEDO_AOV", "NORMAL_AOV", "UV_LAYER"]

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
#: the shader AOV every IR material writes its shading normal to (the normal output)
NORMAL_AOV = "bf_normal"
UV_LAYER = "UVMap"


class MaterialBuilder:
    """Creates node-tree materials and images, registering every datablock in the given entry."""

    # -- images ------------------------------------------------------------------------------------
    def image_from_array(self, name: str, rgba: np.ndarray, colorspace: str, entry: Any) -> Any:
        """A float image from an (H, W, 4) float32 array with row 0 = top (Blender stores bottom-first).
        One bulk ``foreach_set``; the pixels are not packed (export packs them)."""
        bpy = bpy_module()
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
        bpy = bpy_module()
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
        bpy = bpy_module()
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

    def value_map_image(self, name: str, tex: Any, entry: Any) -> Any:
        """A non-colour data texture of a TextureMap's values (roughness, metallic) as a float image."""
        return self._data_image(name, np.repeat(tex.values()[..., None], 3, axis=2), entry)

    def normal_map_image(self, name: str, nmap: Any, entry: Any) -> Any:
        """A non-colour data texture of a NormalMap's RGB (tangent-space normals) as a float image."""
        img = nmap.image()
        rgb = img[..., :3] if img.shape[2] >= 3 else np.repeat(img[..., :1], 3, axis=2)
        v = rgb.astype(np.float32) / 255.0 if rgb.dtype == np.uint8 else rgb.astype(np.float32)
        return self._data_image(name, v, entry)

    def _data_image(self, name: str, rgb: np.ndarray, entry: Any) -> Any:
        rgba = np.ones(rgb.shape[:2] + (4,), dtype=np.float32)
        rgba[..., :3] = rgb
        return self.image_from_array(name, rgba, "Non-Color", entry)

    # -- colour sources (the colour handlers of the translator choose one) -------------------------
    @staticmethod
    def attribute_color(nt: Any, attribute: str, has_alpha: bool) -> tuple[Any, Any]:
        """(colour, alpha) read from the mesh's colour attribute ``attribute``."""
        node = nt.nodes.new("ShaderNodeAttribute")
        node.attribute_type = "GEOMETRY"
        node.attribute_name = attribute
        return node.outputs["Color"], (node.outputs["Alpha"] if has_alpha else 1.0)

    @staticmethod
    def image_color(nt: Any, img: Any, interpolation: str, has_alpha: bool) -> tuple[Any, Any]:
        """(colour, alpha) of the image ``img`` read through the ``UVMap`` layer (repeating)."""
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Closest" if interpolation == "closest" else "Linear"
        tex.extension = "REPEAT"
        uv = nt.nodes.new("ShaderNodeUVMap")
        uv.uv_map = UV_LAYER
        nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
        return tex.outputs["Color"], (tex.outputs["Alpha"] if has_alpha else 1.0)

    @staticmethod
    def _feed(nt: Any, value: Any, socket: Any) -> None:
        if hasattr(value, "links") or hasattr(value, "node"):
            nt.links.new(value, socket)
        else:
            socket.default_value = value

    def alpha(self, nt: Any, material_alpha: float, color_alpha: Any) -> Any:
        """The material's alpha times the colour source's (a constant or a Math node's output)."""
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
    def new_material(self, name: str, entry: Any) -> tuple[Any, Any, Any]:
        """A new two-sided material with an empty node tree: (material, node tree, output node)."""
        bpy = bpy_module()
        mat = entry.add("materials", bpy.data.materials.new(name))
        mat.use_backface_culling = False
        nt = mat.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        out.target = "ALL"
        return mat, nt, out

    def finish(self, nt: Any, out: Any, surface: Any, albedo: Any) -> None:
        """Connect ``surface`` to the output, ``albedo`` to the ``bf_albedo`` AOV and the shading normal (the
        normal map's when the tree has one, else the interpolated normal) to the ``bf_normal`` AOV."""
        nt.links.new(surface, out.inputs["Surface"])
        aov = nt.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = ALBEDO_AOV
        self._feed(nt, albedo, aov.inputs["Color"])
        normal_aov = nt.nodes.new("ShaderNodeOutputAOV")
        normal_aov.aov_name = NORMAL_AOV
        maps = [n for n in nt.nodes if n.bl_idname == "ShaderNodeNormalMap"]
        normal = maps[0].outputs["Normal"] if maps else nt.nodes.new("ShaderNodeNewGeometry").outputs["Normal"]
        nt.links.new(normal, normal_aov.inputs["Color"])

    def glossy(self, nt: Any, material: Any, color: Any, alpha: Any, emission_from_color: float) -> Any:
        """A Glossy BSDF tinted by ``color`` (mixed with a transparent BSDF below alpha 1); returns the
        surface socket. ``emission_from_color`` > 0 adds emission of the colour (point-cloud emission)."""
        bsdf = nt.nodes.new("ShaderNodeBsdfGlossy")
        bsdf.distribution = material.distribution
        bsdf.inputs["Roughness"].default_value = float(material.roughness)
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
        return surface

    def principled(
        self,
        nt: Any,
        name: str,
        material: Any,
        color: Any,
        alpha: Any,
        entry: Any,
        emission_from_color: float,
    ) -> Any:
        """A Principled BSDF node with every input of ``material`` (its texture maps through the UVs) and its
        microfacet ``distribution``."""
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.distribution = material.distribution
        for key, socket in PRINCIPLED_INPUTS.items():
            if key == "alpha":
                continue
            if key in _COLOR_PARAMS:
                bsdf.inputs[socket].default_value = tuple(float(x) for x in material.linear(key))
            elif key == "subsurface_radius":
                bsdf.inputs[socket].default_value = tuple(float(x) for x in material.subsurface_radius)
            else:
                bsdf.inputs[socket].default_value = float(getattr(material, key))
        self._feed(nt, color, bsdf.inputs["Base Color"])
        self._feed(nt, alpha, bsdf.inputs["Alpha"])
        if emission_from_color > 0:
            self._feed(nt, color, bsdf.inputs["Emission Color"])
            bsdf.inputs["Emission Strength"].default_value = float(emission_from_color)
        for key, socket, tex_map in (
            ("roughness_map", "Roughness", material.roughness_map),
            ("metallic_map", "Metallic", material.metallic_map),
        ):
            if tex_map is not None:
                img = self.value_map_image(f"{name}_{key}", tex_map, entry)
                tex = self._uv_texture(nt, img)
                nt.links.new(tex.outputs["Color"], bsdf.inputs[socket])
        nmap = material.normal_map
        if nmap is not None:
            img = self.normal_map_image(f"{name}_normal", nmap, entry)
            tex = self._uv_texture(nt, img)
            node = nt.nodes.new("ShaderNodeNormalMap")
            node.space = "TANGENT"
            node.uv_map = UV_LAYER
            node.inputs["Strength"].default_value = float(nmap.strength)
            nt.links.new(tex.outputs["Color"], node.inputs["Color"])
            nt.links.new(node.outputs["Normal"], bsdf.inputs["Normal"])
        return bsdf

    def wireframe(
        self, nt: Any, name: str, material: Any, surface: Any, color: Any, alpha: Any, entry: Any
    ) -> tuple[Any, Any]:
        """The triangle edges of the mesh drawn over ``surface`` (a second Principled BSDF of the wire
        colour, mixed by a Wireframe node in world units); returns (surface, albedo)."""
        wire = nt.nodes.new("ShaderNodeWireframe")
        wire.use_pixel_size = False
        wire.inputs["Size"].default_value = float(material.wireframe_thickness)
        wire_color = tuple(float(x) for x in material.linear("wireframe_color"))
        wbsdf = self.principled(nt, name, material, wire_color, alpha, entry, 0.0)
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(wire.outputs["Factor"], mix.inputs["Factor"])
        nt.links.new(surface, mix.inputs[1])
        nt.links.new(wbsdf.outputs["BSDF"], mix.inputs[2])
        cmix = nt.nodes.new("ShaderNodeMix")
        cmix.data_type = "RGBA"
        # ShaderNodeMix sockets by type: 0 float factor, 6/7 colour A/B, output 2 colour
        nt.links.new(wire.outputs["Factor"], cmix.inputs[0])
        self._feed(nt, color, cmix.inputs[6])
        cmix.inputs[7].default_value = wire_color
        return mix.outputs[0], cmix.outputs[2]
