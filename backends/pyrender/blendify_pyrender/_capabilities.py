"""The pyrender backend's capability table (no engine import: read by the registry and the core)."""

from __future__ import annotations

from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability

__all__ = ["CAPABILITIES", "capability_table"]

_E, _A = "exact", "approximate"

CAPABILITIES: dict[str, Capability] = {
    "mesh": Capability(_E, "rasterised triangles, both faces shaded"),
    "mesh.vertex_colors": Capability(
        _A, "vertex colours multiply the final shaded colour (pyrender COLOR_0), so they also tint highlights"
    ),
    "mesh.texture": Capability(_E, "sRGB decoded in the shader; float textures are uploaded as 8-bit sRGB"),
    "mesh.file_texture": Capability(_E, "sRGB decoded in the shader; float images are uploaded as 8-bit sRGB"),
    "mesh.faces_material": Capability(_E, "one pyrender primitive per material slot"),
    "mesh.smooth": Capability(_E, "interpolated vertex normals"),
    "pointcloud": Capability(
        _A,
        "spheres tessellated as merged icospheres (subdivision 1, the shared tessellation); larger clouds use "
        "a level of detail: icosphere-0 up to 50k points, octahedra up to 100k, GL points (screen-space "
        "squares of the projected diameter) beyond; listed in result.meta['approximations']",
    ),
    "pointcloud.vertex_colors": Capability(_A, "per-point colours multiply the shaded colour (COLOR_0)"),
    "pointcloud.emission": Capability(_A, "emission added to the shaded colour, clipped at 1; lights nothing else"),
    "primitive.cube": Capability(_E, "shared tessellation"),
    "primitive.circle": Capability(_E, "shared tessellation"),
    "primitive.cylinder": Capability(_E, "shared tessellation"),
    "primitive.plane": Capability(_E, "shared tessellation"),
    "primitive.sphere": Capability(_E, "UV sphere 64x32 (the shared tessellation)"),
    "primitive.ellipsoid": Capability(_E, "UV sphere 64x32 scaled (the shared tessellation)"),
    "primitive.curve": Capability(_E, "tube tessellation shared with the other backends"),
    "shadow_catcher": Capability(
        _A,
        "two colour passes (with and without the other objects); alpha = 1 - shadowed/unshadowed radiance "
        "of the catcher, shadow-mapped shadows",
    ),
    "object.no_shadow": Capability(_E, "the object is left out of the shadow maps"),
    "material.principled": Capability(
        _A,
        "glTF metallic-roughness BRDF (GGX, F0 = 0.04 fixed: IOR, specular level/tint, anisotropy ignored), "
        "base colour / 0.96 diffuse compensation, direct light only; dielectric speculars differ ~5-10%",
    ),
    "material.diffuse_only": Capability(
        _A, "pyrender keeps an F0 = 0.04 GGX lobe; base colour / 0.96 gives -0.8% mean vs Lambert (p95 1.5%)"
    ),
    "material.metallic": Capability(_A, "GGX metal lit by the lights only (no reflections); highlights clip at 1"),
    "material.glossy": Capability(_A, "metallic GGX with the colour as F0 (distribution ignored)"),
    "material.transmission": Capability(_A, "no refraction: drawn alpha-blended with alpha x (1 - 0.7 x weight)"),
    "material.coat": Capability(_A, "coat layer ignored"),
    "material.sheen": Capability(_A, "sheen ignored"),
    "material.subsurface": Capability(_A, "subsurface ignored (base colour shaded as diffuse)"),
    "material.emission": Capability(
        _A, "emission added to the shaded colour (clipped at 1 by the 8-bit pass); it lights nothing else"
    ),
    "material.alpha": Capability(_A, "alpha blending, objects sorted by distance; shadows stay opaque"),
    "material.wireframe": Capability(
        _A, "every triangle edge drawn as a square tube of side wireframe_thickness (world units) over the surface"
    ),
    "material.roughness_map": Capability(_E, "8-bit texture through the mesh UVs"),
    "material.metallic_map": Capability(_A, "8-bit texture; the diffuse compensation uses the mean metallic"),
    "material.normal_map": Capability(
        _A, "tangent frame from screen-space derivatives; strength blends toward the flat normal"
    ),
    "light.point": Capability(
        _A, "intensity P/(4 pi) W/sr exact, but no shadows (pyrender has no point-light shadow maps)"
    ),
    "light.point.soft": Capability(_A, "radius ignored: hard light (spot shadows stay hard)"),
    "light.sun": Capability(_E, "irradiance exact; shadows shadow-mapped (2048^2 over the scene bounds, PCF)"),
    "light.sun.soft": Capability(_A, "angular diameter ignored: hard shadows"),
    "light.spot": Capability(
        _E, "intensity P/(4 pi) W/sr, cone half-angle exact; shadow-mapped shadows (none for cones over 160 deg)"
    ),
    "light.spot.blend": Capability(
        _A, "pyrender's quadratic edge clamp((cos t - cos o)/(cos i - cos o))^2 instead of Cycles' smoothstep"
    ),
    "light.area": Capability(
        _A,
        "a spot light at the centre: on-axis intensity P/pi exact in the far field, cone 25/80 deg instead "
        "of the cosine lobe; hard shadow-mapped shadows",
    ),
    "light.area.disk": Capability(_A, "as light.area (a spot light at the centre)"),
    "light.no_shadow": Capability(_E, "the light's shadow map stays empty"),
    "light.background": Capability(
        _A, "unshadowed ambient term (albedo x radiance), no occlusion; not visible (transparent film)"
    ),
    "light.environment": Capability(
        _A, "uniform ambient light at the map's solid-angle-weighted mean radiance; map not visible"
    ),
    "camera.perspective": Capability(_E, "exact OpenGL projection from K (any principal point)"),
    "camera.orthographic": Capability(_E, "exact orthographic projection with the principal point"),
    "camera.anisotropic": Capability(_E, "fx != fy in the projection matrix"),
    "output.rgb": Capability(
        _E,
        "8-bit colour pass linearised with (x/255)^2.2; anti-aliased with MSAA (EGL) or supersampling, coverage alpha",
    ),
    "output.depth": Capability(_E, "planar z from a float G-buffer pass, one sample at the pixel centre"),
    "output.normal": Capability(_E, "world-space shading normal facing the viewer, G-buffer pass"),
    "output.albedo": Capability(_E, "linear material colour input x texture x vertex colour, G-buffer pass"),
    "output.instance": Capability(_E, "exact ids from the G-buffer pass (no anti-aliasing)"),
}


def capability_table() -> dict[str, Capability]:
    """Every name of ``ALL_FEATURES``; a name this table does not know yet is reported unsupported."""
    table = {}
    for name in ALL_FEATURES:
        table[name] = CAPABILITIES.get(name, Capability("unsupported", "not handled by this backend version"))
    return table
