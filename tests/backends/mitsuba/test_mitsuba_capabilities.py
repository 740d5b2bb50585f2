"""The Mitsuba capability table: declared beside the translator's handlers, and identical to the table
the backend had before the handlers existed (the frozen copy below: feature -> (level, note))."""

from __future__ import annotations

from blendify_mitsuba import MitsubaBackend

from blendify_core.pipeline.capabilities import ALL_FEATURES

#: MitsubaBackend.capabilities() as it was before issue 14 (one dictionary in __init__.py)
FROZEN: dict[str, tuple[str, str]] = {
    "mesh": ("exact", ""),
    "mesh.vertex_colors": ("exact", "mesh attribute 'vertex_color' (linear, interpolated like Cycles)"),
    "mesh.texture": (
        "exact",
        "in-memory bitmap, v -> 1 - v; 8-bit sRGB textures with linear interpolation are upsampled in "
        "encoded space (Cycles interpolates before decoding), up to 1M texels",
    ),
    "mesh.file_texture": ("exact", "read by Mitsuba (8-bit PNG/JPEG, nearest or linear data) or through the IR"),
    "mesh.faces_material": ("exact", "one Mitsuba mesh per material slot"),
    "mesh.smooth": ("exact", "vertex normals"),
    "pointcloud": (
        "exact",
        "analytic spheres up to max_analytic_opaque points for opaque, non-emissive clouds, beyond that "
        "one shape of exact spheres (Embree round curves, each point a segment ending in its sphere, per-point "
        "colours in a bitmap); other clouds analytic spheres up to max_analytic_spheres points, else the IR's merged "
        "icosphere mesh",
    ),  # issue 17: curves (capsules, now spheres) replaced the mesh, analytic spheres beyond 500 points
    "pointcloud.vertex_colors": ("exact", ""),
    "pointcloud.emission": ("approximate", "area emitter on the spheres, front (outer) side only"),
    "primitive.cube": ("exact", "IR tessellation"),
    "primitive.circle": ("exact", "IR tessellation"),
    "primitive.cylinder": ("exact", "IR tessellation"),
    "primitive.plane": ("exact", "IR tessellation"),
    "primitive.sphere": (
        "exact",
        "the IR's shared tessellation (64x32 UV sphere, exact vertex normals), as in Cycles and pyrender",
    ),
    "primitive.ellipsoid": ("exact", "IR tessellation"),
    "primitive.curve": (
        "exact",
        "IR tessellation (tube along the polyline); its reflecting BSDFs decide the side by the geometric normal,"
        " as Cycles does (blendify_mitsuba/sided.py)",
    ),
    "shadow_catcher": (
        "approximate",
        "emulated from three renders (all, the catchers alone, all but the catchers): where a pixel "
        "centre sees the catcher (or the background beside the catcher only), black with alpha = 1 - "
        "shadowed/unshadowed luminance; the other pixels from the render without the catchers (a "
        "catcher neither lights nor shades the objects, as in Cycles), their alpha grown by the shadow "
        "beside them where they also cover a catcher",
    ),
    "object.no_shadow": ("unsupported", "Mitsuba has no per-object shadow visibility"),
    "material.principled": (
        "approximate",
        "uniform colours, isotropic: Cycles' layer model (docs/conventions.md). JIT variants: "
        "blendify_mitsuba/layered.py, a Dr.Jit BSDF with each GGX lobe's own Fresnel, height-correlated "
        "shadowing and Cycles' view-dependent layer weights (tables per viewing cosine), also for opaque "
        "materials with colour textures or vertex colours (the base colour evaluated per point); scalar_rgb "
        "and exported scene files: a sum of Mitsuba's built-in lobes (blendify_mitsuba/principled.py, each "
        "GGX lobe a roughconductor fitted to the albedo curve of Cycles' lobe) holding the cosine-weighted "
        "means of those weights (listed in meta['approximations']). Material sweep: "
        "benchmarks/results/material_sweep.md. Roughness/metallic maps, anisotropy, textured glass, and "
        "textures in scalar_rgb: Mitsuba 'principled' (Disney diffuse, Schlick Fresnel; 3-13 % off on "
        "dielectrics)",
    ),
    "material.diffuse_only": ("exact", "Lambertian 'diffuse' (matches Cycles within 0.1 %)"),
    "material.metallic": (
        "approximate",
        "JIT variants: Cycles' F82-tint Fresnel (blendify_mitsuba/layered.py); scalar_rgb: a roughconductor "
        "whose complex IOR is fitted to the albedo curve of Cycles' metal, scaled to its albedo (a dark "
        "specular tint 2-4 % off there: its dip at grazing angles has no conductor equivalent)",
    ),
    "material.glossy": (
        "approximate",
        "roughconductor with a perfect-mirror Fresnel tinted by the colour; for uniform colours scaled to "
        "Cycles' albedo (height-correlated shadowing, MULTI_GGX compensation)",
    ),
    "material.transmission": (
        "approximate",
        "a solid (one-sided, relative IOR 'ior'), transmittance sqrt(base colour) per crossing, mixed with "
        "the opaque lobes by the layers' weight. JIT variants: rough GGX glass with Cycles' view-dependent "
        "multiple-scattering compensation on each side (blendify_mitsuba/layered.py); scalar_rgb: "
        "roughdielectric scaled so that a white glass sphere in a white furnace is as bright as Cycles' "
        "MULTI_GGX glass (measured table)",
    ),
    "material.coat": (
        "approximate",
        "a dielectric GGX lobe of coat_ior (as the specular layer) over the rest, which it attenuates",
    ),
    "material.sheen": (
        "approximate",
        "a broad GGX lobe scaled to Cycles' sheen albedo (measured with Cycles, "
        "benchmarks/measure_sheen_albedo.py; per viewing cosine in the JIT variants, a fitted roughconductor "
        "in scalar_rgb), attenuating the layers below: not the microfiber lobe",
    ),
    "material.subsurface": ("unsupported", "Mitsuba has no subsurface scattering in the principled BSDF"),
    "material.emission": (
        "approximate",
        "area emitter on the surface: emits from the front side only; with a background/environment light"
        " the coverage alpha is composited from two extra one-bounce passes",
    ),
    "material.alpha": (
        "exact",
        "mask BSDF with the material x colour alpha; its shadows transparent as in Cycles (volpath, or "
        "blendify_path's shadow rays with shadowless lights)",
    ),
    "material.wireframe": (
        "approximate",
        "the points Blender's Wireframe shader marks (within wireframe_thickness / 2 of a triangle edge, "
        "world units) as flat bands on each triangle with the surface's BSDF in the wireframe colour, lifted "
        "less than Mitsuba's ray offset so that they cast no shadow on the surface beneath; flat-shaded "
        "(Cycles shades the wire with the surface's smooth normals). Material sweep: sphere mean within 0.5 %"
        " of Cycles",
    ),
    "material.roughness_map": (
        "approximate",
        "raw bitmap driving principled roughness (the principled BSDF's differences)",
    ),
    "material.metallic_map": (
        "approximate",
        "raw bitmap driving principled metallic (the principled BSDF's differences)",
    ),
    "material.normal_map": (
        "approximate",
        "Mitsuba 'normalmap' (frame dp/du, n x dp/du; strength baked into the map); not compared with Cycles yet",
    ),
    "light.point": ("exact", "point, intensity = P / (4 pi)"),
    "light.point.soft": (
        "approximate",
        "point lights: a sphere emitter of radiance P / (4 pi^2 r^2) (Blender's sphere light with soft "
        "falloff off), hidden from the camera as light.area; spot lights: delta (radius ignored). The light's "
        "null surface also blocks other lights' shadow rays",
    ),
    "light.sun": ("exact", "directional, irradiance = strength"),
    "light.sun.soft": (
        "exact",
        "a distant disk emitter subtending the angular diameter, radiance = strength / (pi sin^2(d/2)), 10000x the"
        " scene's radius away (at most 200000 m), unseen by camera rays; scenes over 200 m in radius keep a delta sun"
        " (listed in meta)",
    ),
    "light.spot": ("exact", "spot, intensity = P / (4 pi), cutoff = spot_size / 2"),
    "light.spot.blend": (
        "exact",
        "Blender's smoothstep falloff as a projected texture (beam_width = cutoff; spots over 176 deg or with "
        "blend bands too narrow for 1024 texels keep Mitsuba's linear ramp, listed in meta)",
    ),
    "light.area": (
        "exact",
        "rectangle with radiance P / (pi A), one-sided, hidden from the camera (hide_emitters; in scenes "
        "with emissive materials its directly seen emission is subtracted: unbiased, noisy at its outline)",
    ),
    "light.area.disk": ("exact", "disk with radiance P / (pi A), one-sided, hidden from the camera as light.area"),
    "light.no_shadow": (
        "exact",
        "integrator 'blendify_path' (blendify_mitsuba.integrator): Mitsuba's path tracer with no visibility "
        "test for these lights' emitter samples; runs in Python, used only in scenes with such lights",
    ),
    "light.background": ("exact", "constant emitter"),
    "light.environment": ("exact", "envmap rotated to Blender's equirectangular mapping"),
    "camera.perspective": ("exact", "perspective sensor with principal-point offsets"),
    "camera.orthographic": ("exact", "orthographic sensor, principal point by translating the camera"),
    "camera.anisotropic": (
        "approximate",
        "fx != fy: colour rendered by a square-pixel camera (columns supersampled k <= 4 times, rows at k"
        " fx/fy per pixel, same samples per target pixel) and box-resampled with exact row overlaps (only"
        " boundary rows split); depth/normal/albedo/instance exact (cast through the target pixel "
        "centres)",
    ),
    "output.rgb": ("exact", ""),
    "output.depth": ("exact", "planar z from pixel-centre ray casts"),
    "output.normal": ("exact", "world shading normal (facing the camera) from pixel-centre ray casts"),
    "output.albedo": ("exact", "the material colour input at the pixel centre"),
    "output.instance": ("exact", "renderable index from pixel-centre ray casts"),
}


def test_capability_table_equals_the_frozen_copy():
    caps = {name: (cap.level, cap.note) for name, cap in MitsubaBackend.capabilities().items()}
    assert set(FROZEN) == set(ALL_FEATURES)
    assert list(caps) == list(ALL_FEATURES)
    for name in ALL_FEATURES:
        assert caps[name] == FROZEN[name], name
