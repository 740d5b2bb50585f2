"""Rendering a translated frame into a RenderResult: the colour, G-buffer and coverage passes, the
anti-aliasing schemes and the shadow-catcher composite, on a pyrender ``Renderer`` drawing into
framebuffers chosen per frame.

Import this module only after :func:`blendify_pyrender._platform.prepare_platform` (it imports OpenGL);
the session imports it once its context exists.

Differences of :class:`FrameRenderer` from pyrender's stock renderer (0.1.45):

- colour pass into a float (RGBA32F) framebuffer with ``samples`` MSAA samples (0 = none): mesh.frag writes
  linear radiance without pyrender's gamma encoding or clamp at 1, alpha = coverage x opacity, read back as
  floats; depth is not read back (geometric outputs come from the G-buffer pass);
- a G-buffer pass without MSAA (our own shaders): planar view depth, world normal, albedo and instance id
  in float32 framebuffers, exact at pixel centres, no face culling (two-sided), so the orthographic depth
  bug of pyrender's depth linearisation does not arise;
- pyrender's ``mesh.frag`` is used with one patch: back faces are shaded with the flipped normal
  (two-sided shading, as Cycles);
- shadow maps skip objects that cast no shadow and lights that cast none;
- point clouds are exact spheres (ray-sphere intersection per pixel centre, or per sample when multisampled)
  in every pass: colour, G-buffer, coverage and shadow maps (BLENDIFY_SPHERE shader variants);
- the shadows of solid glass let its light through, focused as by a ball lens (a caustic:
  shaders/blendify_caustic.glsl, the BLENDIFY_CAUSTIC variant; :func:`lenses`).

The colour pass is linear premultiplied radiance (:func:`color_pass_linear`); where the driver cannot render
into float targets it falls back to pyrender's 8-bit output (gamma 1/2.2, clipped at 1), linearised by
:func:`linearise_rgba8` and listed in ``meta["approximations"]``. Anti-aliasing (:class:`AntiAliasing`) is
"msaa" (multisampled lit pass), "coverage" (plain lit pass plus a supersampled coverage pass,
:func:`apply_coverage`), "ssaa" (supersampled, :func:`box_downsample`) or none.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyrender
import pyrender.renderer as _pyrender_renderer
from OpenGL import GL
from OpenGL.GL import (
    GL_BLEND,
    GL_COLOR,
    GL_COLOR_ATTACHMENT0,
    GL_COLOR_ATTACHMENT1,
    GL_COLOR_BUFFER_BIT,
    GL_COPY_WRITE_BUFFER,
    GL_CULL_FACE,
    GL_DEPTH_ATTACHMENT,
    GL_DEPTH_BUFFER_BIT,
    GL_DEPTH_COMPONENT,
    GL_DEPTH_COMPONENT24,
    GL_DEPTH_TEST,
    GL_DRAW_FRAMEBUFFER,
    GL_FILL,
    GL_FLOAT,
    GL_FRAMEBUFFER,
    GL_FRAMEBUFFER_COMPLETE,
    GL_FRONT_AND_BACK,
    GL_LESS,
    GL_MAX_SAMPLES,
    GL_MULTISAMPLE,
    GL_NEAREST,
    GL_ONE,
    GL_ONE_MINUS_SRC_ALPHA,
    GL_PACK_ALIGNMENT,
    GL_PROGRAM_POINT_SIZE,
    GL_READ_FRAMEBUFFER,
    GL_RED,
    GL_RENDERBUFFER,
    GL_RENDERER,
    GL_RGBA,
    GL_RGBA8,
    GL_RGBA32F,
    GL_SAMPLE_SHADING,
    GL_SRC_ALPHA,
    GL_UNSIGNED_BYTE,
    GL_UNSIGNED_INT,
    GL_VIEWPORT,
    glBindBuffer,
    glBindFramebuffer,
    glBindRenderbuffer,
    glBlendFunc,
    glBlendFuncSeparate,
    glBlitFramebuffer,
    glBufferSubData,
    glCheckFramebufferStatus,
    glClear,
    glClearBufferfv,
    glClearColor,
    glDeleteFramebuffers,
    glDeleteRenderbuffers,
    glDepthFunc,
    glDepthMask,
    glDisable,
    glDrawArraysInstanced,
    glDrawBuffers,
    glDrawElementsInstanced,
    glEnable,
    glFlush,
    glFramebufferRenderbuffer,
    glGenFramebuffers,
    glGenRenderbuffers,
    glGetIntegerv,
    glGetString,
    glMinSampleShading,
    glPixelStorei,
    glPointSize,
    glPolygonMode,
    glReadBuffer,
    glReadPixels,
    glRenderbufferStorage,
    glRenderbufferStorageMultisample,
    glViewport,
)
from pyrender.constants import GLTF, BufFlags, RenderFlags

from blendify_core.errors import RenderError
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings

if TYPE_CHECKING:
    from .session import Engine, Frame

__all__ = [
    "render_frame",
    "AntiAliasing",
    "FrameRenderer",
    "GBuffer",
    "MatrixCamera",
    "linearise_rgba8",
    "color_pass_linear",
    "apply_coverage",
    "box_downsample",
    "COVERAGE_SUPERSAMPLE",
]

_GAMMA = 2.2
#: dense GL-point clouds are thinned to this many points per covered pixel (never below POINTS_MIN_DRAWN)
POINTS_PER_PIXEL = 8
POINTS_MIN_DRAWN = 100_000
#: clouds of sub-pixel spheres are thinned to spheres of about this diameter (pixels) of the same summed area:
#: the blended colour pass costs about its drawn points (small_points of benchmarks/preview_look.py, 150k points
#: of 0.12 px, measured together: 1.0 -> 5.7k points drawn, SSIM 0.575, 123 ms (the earlier preview: 0.505,
#: 125-146 ms); 0.85 -> 7.9k, 0.605, 209 ms; 0.7 -> 12k, 0.647, 303 ms; 0.5 -> 23k, 0.725, 454 ms; all 142k,
#: 0.91, 1.8-2.8 s)
SUBPIXEL_DRAWN_DIAMETER = 1.0
#: the coverage scheme splats clouds of spheres under 1.5 px instead (where float targets render): every sphere is
#: shaded once, as a whole, in a target of SPLAT_WIDTH texels a row (FrameRenderer._shade_points), and its radiance
#: spread over the pixels its projected area overlaps (splat_points) - no thinning, no speckle (small_points of
#: benchmarks/preview_look.py: all 150k spheres for about the time of the 5.7k thinned ones). False: thinned
SPLAT = True
SPLAT_WIDTH = 1024
#: the splat shades at most this many spheres per pixel of the image (one in every k of the splat order, the k - 1
#: after it, its neighbours in space, take its light; each keeps its own colour)
SPLAT_SHADES_PER_PIXEL = 2.0
#: squares of sub-pixel spheres narrower than this (px) count whole in the pixel of their centre (splat_points);
#: 0: every square is split over the pixels it overlaps (small_points: 0.935, 0.25 px: 0.929 for 10 % less time)
SPLAT_ONE_TAP = 0.0
#: depth slabs of the splat, composited front to back (small_points: 1 slab, an order-free mean, SSIM 0.914; 4:
#: 0.928; 8: 0.929; 16: 0.929)
SPLAT_LAYERS = 8
SPLAT_NOTE = (
    "pointcloud: spheres under 1.5 px are each shaded once as a whole (direct light: its mean over the half the "
    "eye sees, a Lambertian sphere's phase function; shadows looked up at the point facing the eye; the world's "
    "light averaged over that half) and splatted: each covers the square of its projected area, a pixel's colour "
    "is the covered-fraction-weighted mean of its spheres (no depth order within a pixel), its coverage "
    "1 - prod(1 - fraction); a sphere is hidden when its centre lies behind a surface drawn before the cloud, and "
    "lies over translucent surfaces in front of it; colour only"
)
#: indirect light from a light probe (probe.py)
PROBE = True
#: every light in the colour pass: scenes with more lights of a type than pyrender binds per draw are rendered
#: in groups of lights that fit and summed (FrameRenderer.light_groups); False: one pass, pyrender's nearest lights
LIGHT_GROUPS = True
#: lights of a type without shadow maps in a pass need no texture units: up to this many are bound per draw
#: (pyrender: 4), the shader's arrays sized to the next power of two above the scene's count (a variant each)
MAX_UNSHADOWED_LIGHTS = 64
#: the coverage pass of the "coverage" anti-aliasing is rendered at 3x the resolution (9 samples/pixel)
COVERAGE_SUPERSAMPLE = 3
_LIN8 = ((np.arange(256, dtype=np.float64) / 255.0) ** _GAMMA).astype(np.float32)
#: the coverage of pixels a cloud's blended spheres cover in part: this share from the blended colour pass (low
#: noise, but a dense cloud's edge saturates whole pixels: +5 % coverage on testing.pointcloud_scene(20000)),
#: the rest from the supersampled coverage pass (exact samples: unbiased, noisy)
OWN_WEIGHT = 0.5
_ALPHA8 = (np.arange(256, dtype=np.float64) / 255.0).astype(np.float32)

_SHADER_DIR = Path(__file__).resolve().parent / "shaders"
_TWO_SIDED_ANCHOR = "vec3 n = normalize(get_normal());"
_TWO_SIDED_PATCH = _TWO_SIDED_ANCHOR + "\n    if (!gl_FrontFacing) { n = -n; }"
#: Blender's spot cone: smoothstep over the blend band (pyrender squares the linear ramp, glTF's suggestion:
#: 16 % less light than Cycles on a plane under a 75 degree spot with blend 0.6). pyrender's uniforms give
#: t = (cos - cos_outer) / (cos_inner - cos_outer), the blend band of blendify_core.ir.physics.spot_cone
_SPOT_ANCHOR = "attenuation = attenuation * attenuation * spot_lights[i].intensity;"
_SPOT_PATCH = "attenuation = attenuation * attenuation * (3.0 - 2.0 * attenuation) * spot_lights[i].intensity;"
#: area lights: the integration over the emitter (shaders/blendify_area.glsl) before main(), and the spot
#: loop's colour of an area light taken from it
_MAIN_ANCHOR = "void main()"
_AREA_ANCHOR = """        vec3 res = compute_brdf(n, v, l, roughness, metallic,
                                f0, c_diff, base_color.rgb, radiance);
#ifdef SPOT_LIGHT_SHADOWS"""
_AREA_PATCH = """        vec3 res = bf_area_u[i].w > 0.5
            ? bf_area_light(i, n, v, roughness, metallic, f0, c_diff, base_color.rgb)
            : compute_brdf(n, v, l, roughness, metallic, f0, c_diff, base_color.rgb, radiance);
#ifdef SPOT_LIGHT_SHADOWS"""
#: shadow acne: pyrender's depth bias lets lit planes shadow themselves in sparse pixels under wide spot
#: cones (area lights: 305 of 2304 plane pixels up to 3 % darker); five times the bias removes it
_BIAS_ANCHOR = "float bias = max(0.001 * (1.0 - nl), 0.0001) / proj_coords.w;"
_BIAS_PATCH = "float bias = max(0.005 * (1.0 - nl), 0.0005) / proj_coords.w;"

# Point clouds as exact spheres: pyrender's mesh and depth shaders get a BLENDIFY_SPHERE variant (the library
# shaders/blendify_sphere_{vert,frag}.glsl inserted before their main()). Each point is a quad spread over the
# sphere's projected box; each fragment intersects its pixel centre's ray with the sphere, shades the hit with
# the sphere's normal (frag_position is the hit point) and writes its depth.
_SPHERE_VERT_MAIN = """
#ifdef BLENDIFY_SPHERE
    gl_Position = bf_sphere_corner(M * inst_m, position, texcoord_0.x, texcoord_0.y);
#endif
"""
_SPHERE_FRAG_DECL = "\n#ifdef BLENDIFY_SPHERE\n#define frag_position bf_sphere_pos\n#endif\n"
_SPHERE_FRAG_MAIN = "#ifdef BLENDIFY_SPHERE\n    bf_sphere_hit();\n#endif\n"
_SPHERE_TEXCOORD = "#ifdef BLENDIFY_SPHERE\nlayout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;\n#endif\n"
#: the per-sphere shading pass (BLENDIFY_POINT_SHADE): one quad over the whole target, each fragment one sphere
_POINT_SHADE_VERT = "#ifdef BLENDIFY_POINT_SHADE\n    gl_Position = vec4(position.xy, 0.0, 1.0);\n#endif\n"
_BRDF_NL = "        float nl = clamp(dot(n, l), 0.001, 1.0);\n"
#: the markers our own shaders hold where the sphere library goes
_SPHERE_MARKERS = ("// @BLENDIFY_SPHERE_VERT@\n", "// @BLENDIFY_SPHERE_FRAG@\n")
_GLASS_DIFFUSE = "    vec3 c_diff = mix(vec3(0.0), base_color.rgb * (1 - min_roughness), 1.0 - metallic);\n"
_GLASS_ALPHA = "    frag_color = clamp(vec4(pow(color.xyz, vec3(1.0/2.2)), color.a * base_color.a), 0.0, 1.0);\n"
#: the float colour pass (BLENDIFY_FLOAT_COLOR, see FrameRenderer.float_color): linear radiance as shaded, only
#: negatives cut (pyrender's line above encodes gamma 1/2.2 and clamps at 1 for its 8-bit framebuffer)
_FLOAT_OUT = (
    "#ifdef BLENDIFY_FLOAT_COLOR\n"
    "    frag_color = vec4(max(color.xyz, 0.0), clamp(color.a * base_color.a, 0.0, 1.0));\n"
    "#else\n" + _GLASS_ALPHA + "#endif\n"
)
#: glass (bf_glass = (transmission weight w, F0, IOR, solid)): no diffuse for the transmitted share T = w (1 - F),
#: F Schlick's Fresnel at the viewing angle.
#: - solid glass (a closed object, not flat): opaque; the transmitted share shows the light of the world (the SH;
#:   the indirect-light probe's map when it was rendered from inside, looked up with parallax from the exit point
#:   on the bounding sphere of radius bf_glass_radius) along the ray refracted in and out as through a sphere (the
#:   exit direction of a sphere depends only on the entry angle: t1 = refract(d, n), exit normal
#:   n - 2 (t1.n) t1), tinted by the base colour at both interfaces (tint^2): the inverted view through a ball;
#: - flat glass (a pane: the exit ray is the entry ray): see-through. Alpha blending gives alpha C + (1 - alpha)
#:   behind, so 1 - alpha = T x max(tint) and the other channels' tint is added with the world's radiance
#:   straight behind (the SH) standing in for "behind".
_GLASS_OPACITY = """    if (bf_glass.x > 0.0) {
        vec3 bf_v = normalize(cam_pos - frag_position);
        float bf_nv = clamp(dot(n, bf_v), 0.0, 1.0);
        float bf_t = bf_glass.x * (1.0 - (bf_glass.y + (1.0 - bf_glass.y) * pow(1.0 - bf_nv, 5.0)));
        vec3 bf_tint = clamp(base_color.rgb * (1.0 - min_roughness), 0.0, 1.0);
        if (bf_glass.w > 0.5) {
            vec3 bf_t1 = refract(-bf_v, n, 1.0 / bf_glass.z);
            vec3 bf_n2 = n - 2.0 * dot(bf_t1, n) * bf_t1;
            vec3 bf_t2 = refract(bf_t1, -bf_n2, bf_glass.z);
            if (dot(bf_t2, bf_t2) < 0.5) {
                bf_t2 = reflect(bf_t1, -bf_n2);  // total internal reflection
            }
            vec3 bf_seen = bf_sh(bf_t2, vec3(1.0, 1.5, 4.0));
#ifdef BLENDIFY_PROBE_MAP
            if (bf_probe_inside > 0.5) {  // from the exit point (on the bounding sphere), with parallax
                bf_seen = bf_probe_radiance(bf_probe_parallax(frag_position + bf_glass_radius * (bf_n2 - n), bf_t2),
                                            roughness);
            }
#endif
            color.xyz += bf_t * bf_tint * bf_seen;
        } else {
            float bf_m = max(max(bf_tint.r, bf_tint.g), bf_tint.b);
            float bf_opacity = max(1.0 - bf_t * bf_m, 1e-3);
            vec3 bf_behind = bf_sh(-bf_v, vec3(1.0, 1.5, 4.0));
            color.xyz = max(color.xyz + bf_t * (bf_tint - bf_m) * bf_behind, 0.0) / bf_opacity;
            color.a *= bf_opacity;
        }
    }
"""
#: (file, anchor, replacement) applied to pyrender's shaders after the patches above: the world's light from
#: spherical harmonics (diffuse and glossy, shaders/blendify_env.glsl), glass, point clouds as exact spheres
_PATCHES = (
    (
        "mesh.frag",
        "uniform vec3 ambient_light;\n",
        "uniform vec3 ambient_light;\nuniform vec4 bf_glass;\nuniform float bf_emission;\n",
    ),
    # emission off while the indirect-light probe is rendered (probe.py: emitters already light as lights)
    (
        "mesh.frag",
        "    color.xyz += emissive * material.emissive_factor;\n",
        "    color.xyz += bf_emission * emissive * material.emissive_factor;\n",
    ),
    ("mesh.frag", _GLASS_DIFFUSE, _GLASS_DIFFUSE + "    c_diff *= 1.0 - bf_glass.x;\n"),
    ("mesh.frag", _GLASS_ALPHA, _GLASS_OPACITY + _GLASS_ALPHA),
    (
        "mesh.frag",
        "    color.xyz += base_color.xyz * ambient_light;\n",
        "    color.xyz += bf_environment(n, normalize(cam_pos - frag_position), roughness, metallic, f0, c_diff);\n",
    ),
    # last: the output line, after the glass patch put its code before it
    ("mesh.frag", _GLASS_ALPHA, _FLOAT_OUT),
)
#: soft shadows (shaders/blendify_shadow.glsl): the shadow look-ups of suns and spot/area lights take the light's size
#: in the BLENDIFY_SOFT variant of mesh.frag, used only for frames with a soft light (its code alone, even when
#: skipped, costs llvmpipe about 30 % of the colour pass)
_SUN_SHADOW = """        float shadow = shadow_calc(
            directional_lights[i].light_matrix,
            directional_lights[i].shadow_map,
            nl
        );"""
_SPOT_SHADOW = """        float shadow = shadow_calc(
            spot_lights[i].light_matrix,
            spot_lights[i].shadow_map,
            nl
        );"""
_SOFT_PATCHES = (
    (
        "mesh.frag",
        _SUN_SHADOW,
        "#ifdef BLENDIFY_SOFT\n"
        """        float shadow = bf_soft_shadow(
            directional_lights[i].light_matrix, directional_lights[i].shadow_map, nl, bf_dir_soft[i], false, n);
#else
""" + _SUN_SHADOW + "\n#endif",
    ),
    (
        "mesh.frag",
        _SPOT_SHADOW,
        "#ifdef BLENDIFY_SOFT\n"
        """        float shadow = bf_soft_shadow(
            spot_lights[i].light_matrix, spot_lights[i].shadow_map, nl, bf_spot_soft[i], true, n);
#else
""" + _SPOT_SHADOW + "\n#endif",
    ),
)
_FRAG_COLOR = "    frag_color = clamp(vec4(pow(color.xyz, vec3(1.0/2.2)), color.a * base_color.a), 0.0, 1.0);\n"
#: (file, anchor, replacement) applied before _PATCHES: the sphere's normal, hit and coverage in mesh.frag (a sphere
#: shaded as a whole scales its direct light, summed before the world's light), its quad in mesh.vert and the
#: shadow maps' mesh_depth.*
_SPHERE_PATCHES = (
    (
        "mesh.frag",
        "    color.xyz += base_color.xyz * ambient_light;\n",
        "#ifdef BLENDIFY_SPHERE\n    color.xyz *= bf_sphere_direct;\n#endif\n"
        "    color.xyz += base_color.xyz * ambient_light;\n",
    ),
    ("mesh.frag", _TWO_SIDED_PATCH, _TWO_SIDED_PATCH + "\n#ifdef BLENDIFY_SPHERE\n    n = bf_sphere_normal;\n#endif"),
    ("mesh.frag", "void main()\n{\n", "void main()\n{\n" + _SPHERE_FRAG_MAIN),
    # a sphere shaded as a whole (BLENDIFY_POINT_SHADE): the mean of n.l over the disc it shows
    (
        "mesh.frag",
        _BRDF_NL,
        "#ifdef BLENDIFY_POINT_SHADE\n        float nl = bf_sphere_phase(dot(n, l));\n#else\n" + _BRDF_NL + "#endif\n",
    ),
    ("mesh.frag", _FRAG_COLOR, _FRAG_COLOR + "#ifdef BLENDIFY_SPHERE\n    frag_color.a *= bf_sphere_cover;\n#endif\n"),
    (
        "mesh.vert",
        "    gl_Position = P * V * M * inst_m * vec4(position, 1);\n",
        "    gl_Position = P * V * M * inst_m * vec4(position, 1);\n" + _SPHERE_VERT_MAIN + _POINT_SHADE_VERT,
    ),
    (
        "mesh_depth.vert",
        "layout(location = 0) in vec3 position;\n",
        "layout(location = 0) in vec3 position;\n" + _SPHERE_TEXCOORD,
    ),
    (
        "mesh_depth.vert",
        "    gl_Position = light_matrix * M * inst_m * vec4(position, 1.0);\n",
        "    gl_Position = light_matrix * M * inst_m * vec4(position, 1.0);\n" + _SPHERE_VERT_MAIN,
    ),
    ("mesh_depth.frag", "void main()\n{\n", "void main()\n{\n" + _SPHERE_FRAG_MAIN),
)
#: the shadowed share of a light, and what solid glass lets through it (shaders/blendify_caustic.glsl)
_SHADOW_ANCHOR = "        res = res * (1.0 - shadow);\n"
_SUN_CAUSTIC = "bf_caustic(-directional_lights[i].direction, true, bf_dir_size[i])"
_SPOT_CAUSTIC = "bf_caustic(spot_lights[i].position, false, bf_spot_size[i])"
#: the glass objects whose light the shadows let through (the first this many, largest first)
MAX_LENSES = 4
#: shadows let the light through solid glass (focused as by a ball lens: shaders/blendify_caustic.glsl)
CAUSTICS = True
CAUSTIC_NOTE = (
    "glass: the shadows of solid glass let its light through (a caustic): each object a ball lens (its bounding "
    "sphere; focusing by the material's IOR for round objects, none for boxy ones), the light's beam traced in 8 "
    "rings (Snell, Schlick's Fresnel at both faces, no light reflected inside), each spread evenly over where it "
    "lands and blurred by the emitter's image, tinted once by the base colour; added where the shadow map hides "
    "the light, whatever else hides it there; point lights cast no shadow, so none"
)


def _caustic_shadow(call: str) -> str:
    return (
        "#ifdef BLENDIFY_CAUSTIC\n"
        f"        res = res * (1.0 - shadow + (shadow > 0.0 ? shadow * {call} : vec3(0.0)));\n"
        "#else\n" + _SHADOW_ANCHOR + "#endif\n"
    )


_patched_dir: str | None = None
_NO_GLASS = np.zeros(4, dtype=np.float32)


def _shader_dir() -> str:
    """A per-process folder holding pyrender's shaders (mesh.frag patched for two-sided shading, Blender's
    spot cone, area lights and exact spheres; mesh_depth.* for the spheres' shadows) and ours."""
    global _patched_dir
    if _patched_dir is not None and os.path.isdir(_patched_dir):
        return _patched_dir
    src = Path(pyrender.__file__).resolve().parent / "shaders"
    dst = tempfile.mkdtemp(prefix="blendify_pyrender_shaders_")
    for f in src.iterdir():
        if f.is_file():
            shutil.copyfile(f, os.path.join(dst, f.name))
    mesh_frag = Path(dst) / "mesh.frag"
    text = mesh_frag.read_text()
    if text.count(_SHADOW_ANCHOR) != 2:
        raise RenderError(
            f"pyrender {pyrender.__version__}: mesh.frag changed (not two {_SHADOW_ANCHOR.strip()!r}); this "
            "backend supports pyrender 0.1.45"
        )
    for anchor in (_TWO_SIDED_ANCHOR, _SPOT_ANCHOR, _MAIN_ANCHOR, _AREA_ANCHOR, _BIAS_ANCHOR):
        if text.count(anchor) != 1:
            raise RenderError(
                f"pyrender {pyrender.__version__}: mesh.frag changed (no single {anchor!r}); this backend "
                "supports pyrender 0.1.45"
            )
    area = (_SHADER_DIR / "blendify_area.glsl").read_text()
    text = text.replace(_TWO_SIDED_ANCHOR, _TWO_SIDED_PATCH, 1).replace(_SPOT_ANCHOR, _SPOT_PATCH, 1)
    text = text.replace(_AREA_ANCHOR, _AREA_PATCH, 1).replace(_MAIN_ANCHOR, area + _MAIN_ANCHOR, 1)
    text = text.replace(_BIAS_ANCHOR, _BIAS_PATCH, 1)
    # the world's light: spherical harmonics (shaders/blendify_env.glsl) instead of the uniform ambient term
    env = (_SHADER_DIR / "blendify_env.glsl").read_text()
    text = text.replace(_MAIN_ANCHOR, env + _MAIN_ANCHOR, 1)
    # soft shadows (shaders/blendify_shadow.glsl), after pyrender's shadow_calc
    soft = (_SHADER_DIR / "blendify_shadow.glsl").read_text()
    text = text.replace(_MAIN_ANCHOR, soft + _MAIN_ANCHOR, 1)
    # light through solid glass (shaders/blendify_caustic.glsl): the shadowed share of suns and spot/area lights
    caustic = (_SHADER_DIR / "blendify_caustic.glsl").read_text()
    lib = f"#ifdef BLENDIFY_CAUSTIC\n#define BF_MAX_LENSES {MAX_LENSES}\n{caustic}#endif\n"
    text = text.replace(_MAIN_ANCHOR, lib + _MAIN_ANCHOR, 1)
    head, sun, spot = text.split(_SHADOW_ANCHOR)
    text = head + _caustic_shadow(_SUN_CAUSTIC) + sun + _caustic_shadow(_SPOT_CAUSTIC) + spot
    mesh_frag.write_text(text)
    for name, anchor, replacement in _SPHERE_PATCHES + _PATCHES + _SOFT_PATCHES:
        path = Path(dst) / name
        text = path.read_text()
        if anchor not in text:
            raise RenderError(
                f"pyrender {pyrender.__version__}: {name} changed (no {anchor.strip()!r}); this backend "
                "supports pyrender 0.1.45"
            )
        path.write_text(text.replace(anchor, replacement, 1))
    # the sphere library: before main() in pyrender's shaders, at the markers in ours
    vert_lib = (_SHADER_DIR / "blendify_sphere_vert.glsl").read_text()
    frag_lib = (_SHADER_DIR / "blendify_sphere_frag.glsl").read_text()
    for name, anchor, lib in (
        ("mesh.vert", "\nvoid main()", vert_lib),
        ("mesh_depth.vert", "\nvoid main()", vert_lib),
        ("mesh_depth.frag", "\nvoid main()", frag_lib),
        ("mesh.frag", "in vec3 frag_position;\n", frag_lib + _SPHERE_FRAG_DECL),
    ):
        path = Path(dst) / name
        text = path.read_text()
        at = text.index(anchor) + (len(anchor) if anchor.startswith("in ") else 0)
        path.write_text(text[:at] + "\n" + lib + text[at:])
    for f in _SHADER_DIR.iterdir():
        if f.suffix in (".vert", ".frag"):
            text = f.read_text().replace(_SPHERE_MARKERS[0], vert_lib).replace(_SPHERE_MARKERS[1], frag_lib)
            Path(dst, f.name).write_text(text)
    atexit.register(shutil.rmtree, dst, True)
    _patched_dir = dst
    return dst


def is_sphere_cloud(primitive: Any) -> bool:
    """Whether a pyrender primitive is a point cloud drawn as exact spheres (see translate.pointcloud)."""
    return getattr(primitive, "point_diameter", None) is not None


#: bf_sphere_mode (shaders/blendify_sphere_frag.glsl): pixel centres on the sphere; pixel centres more than half a
#: pixel inside it, opaque (spheres of 1.5 px and more); the rest of what a sphere covers, with alpha = covered
#: fraction of the pixel (blended)
SPHERE_EXACT, SPHERE_FRINGE, SPHERE_SOLID = 0.0, 2.0, 3.0
#: pixels the quads of the modes grow by around the spheres' projected boxes
_SPHERE_GROW = {SPHERE_EXACT: 0.0, SPHERE_FRINGE: 0.55, SPHERE_SOLID: 0.0}
#: clouds of spheres of 1.5 px and more get blended (anti-aliased) edges in the coverage scheme's colour pass when
#: at most this many points are drawn (the edges about double the shaded pixels); larger clouds keep the
#: scheme's pixel-centre colour and supersampled coverage
BLEND_MAX_POINTS = 50_000


def _bind_sphere_uniforms(program: Any, primitive: Any, mode: float, full: bool) -> None:
    """The sphere variant's uniforms for the current viewport: the mode, the diameter factor of the drawn
    subset (``full``: every point at its own diameter) and whether ``primitive`` is GL points (sprites)."""
    vp = glGetIntegerv(GL_VIEWPORT)
    program.set_uniform("bf_viewport", np.array([vp[2], vp[3]], dtype=np.float32))
    program.set_uniform("bf_sphere_scale", 1.0 if full else float(getattr(primitive, "sphere_scale", 1.0)))
    program.set_uniform("bf_sphere_mode", float(mode))
    program.set_uniform("bf_sphere_grow", _SPHERE_GROW[mode])
    program.set_uniform("bf_sphere_sprite", 1.0 if primitive.mode == GLTF.POINTS else 0.0)


def point_sprites(primitive: Any) -> Any:
    """The GL-points twin of a sphere cloud's quads (one vertex per sphere, same order and attributes), built
    on first use: the blended colour pass draws clouds of sub-pixel spheres with it (a quarter of the vertices
    and half the primitives; the sprites of such spheres are a few pixels, far below GL's point size limit)."""
    twin = getattr(primitive, "point_twin", None)
    if twin is None:
        colors = primitive.color_0
        twin = pyrender.Primitive(
            positions=primitive.positions[::4],
            texcoord_0=primitive.texcoord_0[::4],
            color_0=None if colors is None else colors[::4],
            indices=np.arange(len(primitive.positions) // 4, dtype=np.uint32),
            material=primitive.material,
            mode=GLTF.POINTS,
        )
        twin.point_all_indices = np.arange(len(primitive.positions) // 4, dtype=np.uint32)
        twin._indices = twin.point_all_indices  # uploaded whole; a prefix is drawn
        twin.albedo_factor = primitive.albedo_factor
        primitive.point_twin = twin
    if not twin._in_context():
        twin._add_to_context()
    twin._indices = twin.point_all_indices[: len(primitive.indices) // 2]  # the points the quads draw
    twin.sphere_scale = getattr(primitive, "sphere_scale", 1.0)
    return twin


class _ProgramCache(pyrender.shader_program.ShaderProgramCache):  # type: ignore[misc]
    """pyrender's program cache adding the BLENDIFY_SPHERE define to mesh.vert/mesh.frag and to the
    shadow maps' mesh_depth.vert/frag while ``sphere``, BLENDIFY_SOFT while ``soft`` (the frame has a light with
    soft shadows), BLENDIFY_PROBE_MAP while ``probe_map`` (metals reflect the probe's map), BLENDIFY_PROBE_GRID
    while ``probe_grid`` (indirect light from a grid of probes), BLENDIFY_CAUSTIC while ``caustic`` (shadows let
    the light of solid glass through), BLENDIFY_FLOAT_COLOR while ``float_color`` (linear output for the float
    colour pass) and BLENDIFY_POINT_SHADE (with BLENDIFY_FLOAT_COLOR) while ``point_shade`` (each sphere of a
    cloud shaded once, FrameRenderer._shade_points). Unused code still costs
    llvmpipe: each is a variant."""

    sphere = False
    soft = False
    probe_map = False
    float_color = False
    probe_grid = False
    caustic = False
    point_shade = False

    def get_program(
        self, vertex_shader: str, fragment_shader: str, geometry_shader: Any = None, defines: Any = None
    ) -> Any:
        if self.sphere and vertex_shader in ("mesh.vert", "mesh_depth.vert"):
            defines = {**(defines or {}), "BLENDIFY_SPHERE": 1}
        if self.soft and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_SOFT": 1}
        if self.probe_map and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_PROBE_MAP": 1}
        if self.float_color and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_FLOAT_COLOR": 1}
        if self.probe_grid and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_PROBE_GRID": 1}
        if self.caustic and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_CAUSTIC": 1}
        if self.point_shade and vertex_shader == "mesh.vert":
            defines = {**(defines or {}), "BLENDIFY_POINT_SHADE": 1, "BLENDIFY_FLOAT_COLOR": 1}
        return super().get_program(vertex_shader, fragment_shader, geometry_shader, defines)


def _is_solid(primitive: Any) -> bool:
    """Whether a primitive is a solid (not flat: thicker than 1 % of its extent along every axis), cached."""
    solid = getattr(primitive, "blendify_solid", None)
    if solid is None:
        extent = np.ptp(np.asarray(primitive.positions, dtype=np.float64), axis=0)
        solid = bool(extent.min() > 0.01 * extent.max())
        primitive.blendify_solid = solid
    return bool(solid)


def lenses(scene: Any, nodes: list[Any], skip: set[Any]) -> tuple[np.ndarray, list[str]]:
    """The solid glass objects among ``nodes`` (not in ``skip``: they cast no shadow) as the ball lenses of the
    caustic term (shaders/blendify_caustic.glsl): (n, 2, 4) float32 rows (centre, radius of the bounding sphere
    about the box centre) and (transmittance rgb = transmission weight x base colour, IOR of the focusing), at
    most :data:`MAX_LENSES`, largest first; and notes on what was left out. The focusing IOR is the material's
    for round objects (a mesh filling its bounding sphere), falling to 1 (the light passes unfocused, as through
    a slab) for objects filling half of it or less (a cube fills 37 %)."""
    found: list[tuple[float, np.ndarray]] = []
    for node in nodes:
        if node is None or node in skip or not node.mesh.is_visible:
            continue
        prims = [
            p
            for p in node.mesh.primitives
            if getattr(p.material, "blendify_glass", None) is not None
            and float(p.material.blendify_glass[0]) > 0.0
            and _is_solid(p)
        ]
        if not prims:
            continue
        pose = np.asarray(scene.get_pose(node), dtype=np.float64)
        pts = np.concatenate([np.asarray(p.positions, dtype=np.float64) for p in prims])
        world = pts @ pose[:3, :3].T + pose[:3, 3]
        centre = 0.5 * (world.min(axis=0) + world.max(axis=0))
        radius = float(np.sqrt(((world - centre) ** 2).sum(axis=1).max()))
        if radius <= 0.0:
            continue
        volume = sum(_volume(p) for p in prims) * abs(float(np.linalg.det(pose[:3, :3])))
        fill = volume / (4.0 / 3.0 * np.pi * radius**3)
        glass = prims[0].material.blendify_glass
        base = np.clip(np.asarray(prims[0].material.baseColorFactor, dtype=np.float64)[:3], 0.0, 1.0)
        focus = 1.0 + (float(glass[2]) - 1.0) * float(np.clip((fill - 0.5) / 0.4, 0.0, 1.0))
        # the shader's Fresnel is that of the focusing IOR: scaled to the material's at normal incidence
        fresnel = ((1.0 - float(glass[1])) / (1.0 - ((focus - 1.0) / (focus + 1.0)) ** 2)) ** 2
        row = np.array([[*centre, radius], [*(float(glass[0]) * fresnel * base), focus]], dtype=np.float32)
        found.append((radius, row))
    found.sort(key=lambda t: -t[0])
    notes = []
    if len(found) > MAX_LENSES:
        notes.append(
            f"glass: the light through the {MAX_LENSES} largest solid glass objects reaches their shadows; "
            f"{len(found) - MAX_LENSES} smaller one(s) cast plain shadows"
        )
    rows = [r for _, r in found[:MAX_LENSES]]
    return (np.stack(rows) if rows else np.zeros((0, 2, 4), dtype=np.float32)), notes


def _bounding_radius(primitive: Any, pose: Any) -> float:
    """The radius of the sphere about a primitive's box centre holding it, in world units (local radius cached,
    times the pose's largest scale)."""
    local = getattr(primitive, "blendify_radius", None)
    if local is None:
        pts = np.asarray(primitive.positions, dtype=np.float64)
        centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        local = float(np.sqrt(((pts - centre) ** 2).sum(axis=1).max()))
        primitive.blendify_radius = local
    scale = float(np.linalg.norm(np.asarray(pose, dtype=np.float64)[:3, :3], axis=0).max())
    return float(local) * scale


def _volume(primitive: Any) -> float:
    """The volume a triangle primitive encloses (divergence theorem; 0 for other modes), cached."""
    vol = getattr(primitive, "blendify_volume", None)
    if vol is None:
        vol = 0.0
        if primitive.mode == GLTF.TRIANGLES:
            pos = np.asarray(primitive.positions, dtype=np.float64)
            idx = primitive.indices
            tri = pos[np.asarray(idx).reshape(-1, 3)] if idx is not None else pos.reshape(-1, 3, 3)
            vol = abs(float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6.0)
        primitive.blendify_volume = vol
    return float(vol)


def _set_optional(program: Any, name: str, value: Any) -> None:
    """Set a uniform that this program may not use (the compiler drops unused ones)."""
    try:
        program.set_uniform(name, value)
    except ValueError:
        pass


def _soft_params(light: Any, scene_scale: float) -> np.ndarray:
    """The soft-shadow uniform of a light (shaders/blendify_shadow.glsl) for pyrender's shadow camera of a scene
    of bounding-box diagonal ``scene_scale``: spot/area lights (emitter radius, near, far, tan(half fov)), suns
    (tan(half angular diameter), near, far, half width); size 0 (``light.blendify_soft`` unset): hard shadows."""
    out = np.zeros(4, dtype=np.float32)
    size = float(getattr(light, "blendify_soft", 0.0))
    if size <= 0.0:
        return out
    s = float(scene_scale)
    out[:3] = (size, 0.01 * s, 10.0 * s)  # pyrender's shadow cameras (light.py: _get_shadow_camera)
    if isinstance(light, pyrender.SpotLight):
        out[3] = np.tan(0.5 * float(np.clip(2 * light.outerConeAngle + np.pi / 16.0, 0.0, np.pi)))
    else:
        out[3] = s
    return out


def _blend_func_alpha_over(sfactor: int, dfactor: int) -> None:
    """``glBlendFunc`` with the alpha channel composited "over" (correct coverage alpha)."""
    if sfactor == GL_SRC_ALPHA:
        glBlendFuncSeparate(sfactor, dfactor, GL_ONE, GL_ONE_MINUS_SRC_ALPHA)
    else:
        glBlendFunc(sfactor, dfactor)


def _buffer_defines(primitive: Any) -> dict[str, int]:
    """Attribute locations of a pyrender primitive's vertex array (the order ``_add_to_context`` uses)."""
    bf = primitive.buf_flags
    defines: dict[str, int] = {}
    loc = 1
    for flag, name in (
        (BufFlags.NORMAL, "NORMAL_LOC"),
        (BufFlags.TANGENT, "TANGENT_LOC"),
        (BufFlags.TEXCOORD_0, "TEXCOORD_0_LOC"),
        (BufFlags.TEXCOORD_1, "TEXCOORD_1_LOC"),
        (BufFlags.COLOR_0, "COLOR_0_LOC"),
    ):
        if bf & flag:
            defines[name] = loc
            loc += 1
    defines["INST_M_LOC"] = loc
    return defines


class GBuffer:
    """Float G-buffer of one frame (rows top to bottom): ``geom`` (H, W, 4) = world normal xyz + planar
    depth, ``surface`` (H, W, 4) = albedo rgb + (instance id + 1); both 0 where nothing was hit."""

    def __init__(self, geom: np.ndarray, surface: np.ndarray) -> None:
        self.geom = geom
        self.surface = surface

    @property
    def hit(self) -> np.ndarray:
        return self.surface[..., 3] > 0.5

    @property
    def depth(self) -> np.ndarray:
        return np.where(self.hit, self.geom[..., 3], np.inf).astype(np.float32)

    @property
    def normal(self) -> np.ndarray:
        n = self.geom[..., :3]
        length = np.linalg.norm(n, axis=-1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0).astype(np.float32)

    @property
    def albedo(self) -> np.ndarray:
        return np.ascontiguousarray(self.surface[..., :3], dtype=np.float32)

    @property
    def instance(self) -> np.ndarray:
        return np.rint(self.surface[..., 3]).astype(np.int32) - 1


class _FloatTexture:
    """A linearly (or nearest) filtered RGB or RGBA float 2D texture (pyrender's textures are 8-bit) that
    pyrender's ``_bind_texture`` can bind."""

    def __init__(self, data: np.ndarray, nearest: bool = False) -> None:
        h, w, c = data.shape
        self.id = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
        filt = GL.GL_NEAREST if nearest else GL.GL_LINEAR
        for param, value in (
            (GL.GL_TEXTURE_MIN_FILTER, filt),
            (GL.GL_TEXTURE_MAG_FILTER, filt),
            (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE),
            (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE),
        ):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, param, value)
        glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        pixels = np.zeros((h, w, 4), dtype=np.float32)  # RGBA: llvmpipe filters it faster than RGB
        pixels[..., :c] = data
        GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, pixels)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    def _bind(self) -> None:
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)

    def delete(self) -> None:
        GL.glDeleteTextures([self.id])


class FrameRenderer(pyrender.Renderer):
    """pyrender's renderer with per-frame framebuffers (see the module docstring)."""

    #: the scene's (directional, spot, point) light counts of the current colour pass (light_groups)
    _light_counts: tuple[int, int, int] = (0, 0, 0)

    def __init__(self) -> None:
        super().__init__(1, 1)
        self._program_cache = _ProgramCache(shader_dir=_shader_dir())
        self.max_samples = int(glGetIntegerv(GL_MAX_SAMPLES))
        self.gl_renderer = (glGetString(GL_RENDERER) or b"").decode("ascii", "replace")
        self._targets: dict[tuple[str, int, int, int, bool], dict[str, Any]] = {}
        self._target: tuple[int, int, int] = (1, 1, 0)
        self._shadow_light: Any = None
        #: nodes that cast no shadow / lights that cast none / nodes hidden in the current pass
        self.no_shadow_nodes: set[Any] = set()
        self.no_shadow_lights: set[Any] = set()
        #: identifies the shadow-casting state (geometry, poses, lights, hidden nodes); shadow maps are
        #: view independent, so while it stays the same they are reused instead of re-rendered (None = always)
        self.shadow_key: Any = None
        self._shadow_done: dict[Any, Any] = {}
        #: single-sample colour passes draw point clouds' spheres exactly at pixel centres (False) or as opaque
        #: interiors plus edges and sub-pixel spheres blended by the fraction of the pixel they cover (True)
        self.sphere_blend = False
        #: the world's light as 9 SH coefficients (A_l / pi) L_lm, linear RGB (translate.environment_sh)
        self.env_sh = np.zeros((9, 3), dtype=np.float32)
        #: the light glossy and metal surfaces reflect (the world's; env_sh may be the indirect-light probe's)
        self.spec_sh = np.zeros((9, 3), dtype=np.float32)
        #: emission scale (0 while the indirect-light probe is rendered)
        self.emission_scale = 1.0
        #: what the indirect-light probe sees, as an equirectangular texture metals reflect (probe.py), its
        #: radiance scale (the 8-bit texture holds radiance / scale) and whether it is used (0 while the probe renders)
        self.probe_texture: Any = None
        self.probe_map_scale = 0.0
        #: where the map was rendered from and the box of its surroundings (rows point, min, max)
        self.probe_map_frame = np.zeros((3, 3), dtype=np.float32)
        self.probe_scale = 1.0
        #: the indirect-light probe of the last frame: (key, coefficients, grid, note) (probe.py)
        self.probe_cache: tuple[Any, np.ndarray, Any, str] | None = None
        #: the grid of indirect-light probes as a 3D texture (probe.ProbeGrid; None: none) and its uniforms
        self.probe_grid: Any = None
        self.probe_grid_box: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        #: the solid glass objects as ball lenses (:func:`lenses`): (n, 2, 4) float32, rows (centre, radius) and
        #: (transmittance rgb, IOR of the focusing); bound in the BLENDIFY_CAUSTIC variant
        self.lenses = np.zeros((0, 2, 4), dtype=np.float32)
        #: while not None (the probes' renders: the same lights and world light for every face), a program's
        #: light uniforms are set once: (program, node, first texture unit, world light) -> (texture binds, next unit)
        self.lighting_cache: dict[Any, tuple[list[tuple[int, Any]], int]] | None = None
        self._texture_log: list[tuple[int, Any]] | None = None
        self.float_targets = self.float_targets_supported()
        self.float_color = self.float_targets
        self.max_texture_size = int(glGetIntegerv(GL.GL_MAX_TEXTURE_SIZE))
        #: while True (the coverage scheme's colour pass), clouds marked ``point_splat`` (_thin_clouds) are shaded
        #: sphere by sphere (:meth:`_shade_points`) instead of drawn; the radiance lands in ``splat_shades``:
        #: id(primitive) -> (primitive, pose, (M, 4) radiance and opacity of every stride-th sphere of the splat
        #: order, (H, W) window depth drawn before it, stride)
        self.point_splat = False
        self.splat_shades: dict[int, tuple[Any, np.ndarray, np.ndarray, np.ndarray, int]] = {}
        #: per cloud: (the cloud, its shading pass's quad, its spheres' texture) (:meth:`_splat_inputs`)
        self._splat_inputs_of: dict[int, tuple[Any, Any, Any]] = {}
        #: primitives the coverage pass leaves out (splatted clouds bring their own coverage)
        self.coverage_skip: set[int] = set()

    @property
    def float_color(self) -> bool:
        """Whether the colour pass renders linear radiance into float targets (RGBA32F, read back as floats);
        False: pyrender's 8-bit gamma-encoded output (the fallback where the driver has no float targets)."""
        return bool(self._program_cache.float_color)

    @float_color.setter
    def float_color(self, value: bool) -> None:
        self._program_cache.float_color = bool(value)

    def float_targets_supported(self) -> bool:
        """Whether RGBA32F renderbuffers are complete colour targets here, single-sampled and with the most
        samples the driver allows (a 4 x 4 trial)."""
        ok = True
        for samples in (0, self.max_samples) if self.max_samples >= 2 else (0,):
            rb = glGenRenderbuffers(1)
            fbo = glGenFramebuffers(1)
            try:
                glBindRenderbuffer(GL_RENDERBUFFER, rb)
                if samples > 0:
                    glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA32F, 4, 4)
                else:
                    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA32F, 4, 4)
                glBindFramebuffer(GL_FRAMEBUFFER, fbo)
                glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb)
                ok = ok and glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE
            except Exception:  # a GL error raised by PyOpenGL: the format is not renderable
                ok = False
            finally:
                glBindFramebuffer(GL_FRAMEBUFFER, 0)
                glDeleteFramebuffers(1, [fbo])
                glDeleteRenderbuffers(1, [rb])
        return ok

    # -- framebuffers ----------------------------------------------------------------------------
    def _framebuffer(self, kind: str, width: int, height: int, samples: int) -> dict[str, Any]:
        floats = (kind == "color" and self.float_color) or kind == "points"
        key = (kind, width, height, samples, floats)
        fb = self._targets.get(key)
        if fb is not None:
            return fb
        # keep one size per kind: drop stale targets of this kind
        for old in [k for k in self._targets if k[0] == kind]:
            self._free_target(self._targets.pop(old))
        fb = {"fbos": [], "rbs": []}
        if kind in ("color", "coverage", "points"):
            fmt = GL_RGBA32F if floats else GL_RGBA8
            color_rb, depth_rb = glGenRenderbuffers(2)
            glBindRenderbuffer(GL_RENDERBUFFER, color_rb)
            if samples > 0:
                glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, fmt, width, height)
            else:
                glRenderbufferStorage(GL_RENDERBUFFER, fmt, width, height)
            glBindRenderbuffer(GL_RENDERBUFFER, depth_rb)
            if samples > 0:
                glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH_COMPONENT24, width, height)
            else:
                glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height)
            draw = glGenFramebuffers(1)
            glBindFramebuffer(GL_FRAMEBUFFER, draw)
            glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb)
            glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb)
            self._check_complete("colour")
            fb["fbos"].append(draw)
            fb["rbs"] += [color_rb, depth_rb]
            fb["draw"] = draw
            fb["read"] = draw
            if samples > 0:
                resolve_rb = glGenRenderbuffers(1)
                glBindRenderbuffer(GL_RENDERBUFFER, resolve_rb)
                glRenderbufferStorage(GL_RENDERBUFFER, fmt, width, height)
                resolve = glGenFramebuffers(1)
                glBindFramebuffer(GL_FRAMEBUFFER, resolve)
                glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, resolve_rb)
                self._check_complete("resolve")
                fb["fbos"].append(resolve)
                fb["rbs"].append(resolve_rb)
                fb["read"] = resolve
        else:  # G-buffer: two float attachments + depth, never multisampled
            rbs = list(glGenRenderbuffers(3))
            for rb, fmt in zip(rbs, (GL_RGBA32F, GL_RGBA32F, GL_DEPTH_COMPONENT24)):
                glBindRenderbuffer(GL_RENDERBUFFER, rb)
                glRenderbufferStorage(GL_RENDERBUFFER, fmt, width, height)
            draw = glGenFramebuffers(1)
            glBindFramebuffer(GL_FRAMEBUFFER, draw)
            glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rbs[0])
            glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, rbs[1])
            glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rbs[2])
            self._check_complete("G-buffer")
            fb["fbos"].append(draw)
            fb["rbs"] += rbs
            fb["draw"] = fb["read"] = draw
        glBindFramebuffer(GL_FRAMEBUFFER, 0)
        self._targets[key] = fb
        return fb

    @staticmethod
    def _check_complete(what: str) -> None:
        status = glCheckFramebufferStatus(GL_FRAMEBUFFER)
        if status != GL_FRAMEBUFFER_COMPLETE:
            raise RenderError(f"pyrender: the {what} framebuffer is incomplete (status 0x{int(status):x})")

    @staticmethod
    def _free_target(fb: dict[str, Any]) -> None:
        if fb["fbos"]:
            glDeleteFramebuffers(len(fb["fbos"]), fb["fbos"])
        if fb["rbs"]:
            glDeleteRenderbuffers(len(fb["rbs"]), fb["rbs"])

    # pyrender hooks: the forward pass binds self._main_fb_ms and reads through _read_main_framebuffer
    def _configure_main_framebuffer(self) -> None:
        w, h, samples = self._target
        self._main_fb_ms = self._framebuffer("color", w, h, samples)["draw"]

    def _delete_main_framebuffer(self) -> None:
        for fb in self._targets.values():
            self._free_target(fb)
        self._targets = {}
        self._main_fb_ms = None

    def _read_main_framebuffer(self, scene: Any, flags: int) -> Any:
        w, h, samples = self._target
        fb = self._framebuffer("color", w, h, samples)
        if samples > 0:
            glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["draw"])
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb["read"])
            glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST)
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["read"])
        glReadBuffer(GL_COLOR_ATTACHMENT0)
        gl_type, dtype = (GL_FLOAT, np.float32) if self.float_color else (GL_UNSIGNED_BYTE, np.uint8)
        img = np.frombuffer(glReadPixels(0, 0, w, h, GL_RGBA, gl_type), dtype=dtype).reshape(h, w, 4)
        return img[::-1], None

    # -- lights ----------------------------------------------------------------------------------
    def _next_unit(self) -> int:
        """The texture unit pyrender's ``_bind_texture`` binds next."""
        return int(self.__dict__["_texture_alloc_idx"])

    def _bind_texture(self, texture: Any, uniform_name: str, program: Any) -> None:
        if self._texture_log is not None:
            self._texture_log.append((self._next_unit(), texture))
        super()._bind_texture(texture, uniform_name, program)

    def _bind_lighting(self, scene: Any, program: Any, node: Any, flags: int) -> None:
        """The light uniforms (:meth:`_bind_lights`); with ``lighting_cache`` set, once per program (its
        uniforms persist): later draws only bind the same textures to the same units."""
        if self.lighting_cache is None:
            self._bind_lights(scene, program, node, flags)
            return
        key = (
            program,
            node,  # pyrender binds the lights nearest to the node when there are too many
            frozenset(scene.directional_light_nodes),  # the light group of the pass (light_groups)
            frozenset(scene.spot_light_nodes),
            frozenset(scene.point_light_nodes),
            self._next_unit(),
            self.env_sh.tobytes(),
            self.spec_sh.tobytes(),
            id(self.probe_grid),
            id(self.probe_texture),
            self.probe_scale,
            self.probe_map_frame.tobytes(),
            self.lenses.tobytes(),
        )
        hit = self.lighting_cache.get(key)
        if hit is None:
            self._texture_log = []
            try:
                self._bind_lights(scene, program, node, flags)
                self.lighting_cache[key] = (self._texture_log, self._next_unit())
            finally:
                self._texture_log = None
            return
        for unit, texture in hit[0]:
            GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
            texture._bind()
        self._texture_alloc_idx = hit[1]

    def _bind_lights(self, scene: Any, program: Any, node: Any, flags: int) -> None:
        """pyrender's light uniforms, then the area-light uniforms of every spot light it bound, in the
        same order (``light.blendify_area`` = (shape, half x, half y) marks an area light)."""
        super()._bind_lighting(scene, program, node, flags)
        max_n = self._compute_max_n_lights(flags)
        nodes = scene.light_nodes
        if (
            len(scene.directional_light_nodes) > max_n[0]
            or len(scene.spot_light_nodes) > max_n[1]
            or len(scene.point_light_nodes) > max_n[2]
        ):
            nodes = self._sorted_nodes_by_distance(scene, scene.light_nodes, node)
        k = d = 0
        for n in nodes:
            if isinstance(n.light, pyrender.DirectionalLight):
                if d < max_n[0]:
                    _set_optional(program, f"bf_dir_soft[{d}]", _soft_params(n.light, scene.scale))
                    _set_optional(program, f"bf_dir_size[{d}]", float(getattr(n.light, "blendify_soft", 0.0)))
                    d += 1
                continue
            if not isinstance(n.light, pyrender.SpotLight):
                continue
            if k == max_n[1]:
                continue
            u = np.zeros(4, dtype=np.float32)
            v = np.zeros(4, dtype=np.float32)
            area = getattr(n.light, "blendify_area", None)
            if area is not None:
                shape, half_x, half_y = area
                pose = scene.get_pose(n)
                u[:3], u[3] = pose[:3, 0] * half_x, shape
                v[:3] = pose[:3, 1] * half_y
            _set_optional(program, f"bf_area_u[{k}]", u)
            _set_optional(program, f"bf_area_v[{k}]", v)
            _set_optional(program, f"bf_spot_soft[{k}]", _soft_params(n.light, scene.scale))
            _set_optional(program, f"bf_spot_size[{k}]", float(getattr(n.light, "blendify_soft", 0.0)))
            k += 1
        if self._program_cache.caustic:  # the BLENDIFY_CAUSTIC variant
            program.set_uniform("bf_n_lenses", len(self.lenses))
            for j, (lens, through) in enumerate(self.lenses):
                program.set_uniform(f"bf_lens[{j}]", lens)
                program.set_uniform(f"bf_lens_t[{j}]", through)
        if self.probe_texture is not None and self.probe_scale > 0.0:  # the BLENDIFY_PROBE_MAP variant
            self._bind_texture(self.probe_texture, "bf_probe_map", program)
            program.set_uniform("bf_probe_scale", float(self.probe_map_scale))
            for name, value in zip(("bf_probe_point", "bf_proxy_lo", "bf_proxy_hi"), self.probe_map_frame):
                _set_optional(program, name, value)
        if self.probe_grid is not None:  # the BLENDIFY_PROBE_GRID variant
            self._bind_texture(self.probe_grid, "bf_grid", program)
            if self.probe_grid_box is None:  # set together with the grid texture (set_probe_grid)
                raise RenderError("pyrender: the light-probe grid has a texture but no bounds")
            for name, value in zip(("bf_grid_lo", "bf_grid_size", "bf_grid_n"), self.probe_grid_box):
                program.set_uniform(name, value)
        for i in range(9):  # the world's light (shaders/blendify_env.glsl)
            program.set_uniform(f"bf_env_sh[{i}]", self.env_sh[i])
            program.set_uniform(f"bf_spec_sh[{i}]", self.spec_sh[i])

    def set_probe_map(self, radiance: np.ndarray | None, point: Any = None, box: tuple[Any, Any] | None = None) -> None:
        """Upload what the indirect-light probe sees ((H, 2H, 3) linear radiance; None: no map) from ``point``,
        its surroundings taken to lie on the faces of ``box`` (world min, max; with the point: solid glass
        looks up the map with parallax)."""
        if self.probe_texture is not None:
            self.probe_texture.delete()
            self.probe_texture = None
        self.probe_map_scale = 0.0
        if radiance is None:
            return
        if point is not None and box is not None:
            lo = np.minimum(np.asarray(box[0], np.float64), point)
            hi = np.maximum(np.asarray(box[1], np.float64), point)
            self.probe_map_frame = np.stack([np.asarray(point, np.float64), lo, hi]).astype(np.float32)
        scale = max(float(radiance.max(initial=0.0)), 1e-6)
        # 8 bits, gamma 2.2 (as pyrender's colour): radiance = scale x value^2.2
        u8 = np.round(np.clip(radiance / scale, 0.0, 1.0) ** (1.0 / _GAMMA) * 255.0).astype(np.uint8)
        sampler = pyrender.Sampler(
            magFilter=GLTF.LINEAR, minFilter=GLTF.LINEAR_MIPMAP_LINEAR, wrapS=GLTF.REPEAT, wrapT=GLTF.CLAMP_TO_EDGE
        )
        self.probe_texture = pyrender.Texture(source=u8, source_channels="RGB", sampler=sampler)
        self.probe_texture._add_to_context()
        self.probe_map_scale = scale

    def set_probe_grid(self, grid: Any) -> None:
        """Upload the indirect light of a grid of probes (probe.ProbeGrid; None: no grid) as a float texture of
        nx x (9 nz ny) texels: coefficient k of probe (i, j, l) at (i, (k nz + l) ny + j), filtered linearly
        (shaders/blendify_env.glsl keeps the look-ups inside one slab of ny rows and interpolates across
        slabs). A 2D texture: a sampler3D may not share texture unit 0 with pyrender's unset sampler2Ds."""
        if self.probe_grid is not None:
            self.probe_grid.delete()
            self.probe_grid = None
            self.probe_grid_box = None
        if grid is None:
            return
        nx, ny, nz = grid.dims
        data = np.asarray(grid.sh, dtype=np.float32).reshape(nz, ny, nx, 9, 3).transpose(3, 0, 1, 2, 4)
        self.probe_grid = _FloatTexture(data.reshape(9 * nz * ny, nx, 3))
        size = np.maximum(np.asarray(grid.hi, np.float64) - grid.lo, 1e-9)
        self.probe_grid_box = (
            np.asarray(grid.lo, dtype=np.float32),
            size.astype(np.float32),
            np.array(grid.dims, dtype=np.float32),
        )

    # -- point clouds as exact spheres ------------------------------------------------------------
    def _get_primitive_program(self, primitive: Any, flags: int, program_flags: int) -> Any:
        self._program_cache.sphere = is_sphere_cloud(primitive)
        self._program_cache.probe_map = self.probe_texture is not None and self.probe_scale > 0.0
        self._program_cache.probe_grid = self.probe_grid is not None
        self._program_cache.point_shade = self._splatting(primitive)
        try:
            return super()._get_primitive_program(primitive, flags, program_flags)
        finally:
            self._program_cache.sphere = False
            self._program_cache.point_shade = False

    def _splatting(self, primitive: Any) -> bool:
        """Whether this draw shades a cloud sphere by sphere for the splat (:meth:`_shade_points`)."""
        return (
            self.point_splat
            and self._shadow_light is None
            and self._target[2] == 0
            and bool(getattr(primitive, "point_splat", False))
        )

    def _bind_and_draw_primitive(self, primitive: Any, pose: Any, program: Any, flags: int) -> None:
        glass = getattr(primitive.material, "blendify_glass", None)
        if glass is not None:
            glass = glass.copy()
            glass[3] = 1.0 if _is_solid(primitive) else 0.0
        program.set_uniform("bf_glass", _NO_GLASS if glass is None else glass)
        if glass is not None and glass[3] > 0.0 and self.probe_texture is not None:  # its exit points' radius
            _set_optional(program, "bf_glass_radius", _bounding_radius(primitive, pose))
        program.set_uniform("bf_emission", float(self.emission_scale))
        program.set_uniform("bf_probe_inside", 1.0 if getattr(primitive, "blendify_probe_inside", False) else 0.0)
        if not is_sphere_cloud(primitive):
            super()._bind_and_draw_primitive(primitive, pose, program, flags)
            return
        if self._splatting(primitive):
            self._shade_points(primitive, pose, program, flags)
            return
        shadow = self._shadow_light is not None  # shadow maps: every sphere, exact
        # multisampled colour: the sphere is intersected at every sample (gl_FragCoord is the sample's
        # position under sample shading), so its silhouette is anti-aliased like a mesh's (llvmpipe shades
        # every sample of a multisampled pass anyway)
        per_sample = not shadow and self._target[2] > 0
        blend = not shadow and not per_sample and self.sphere_blend
        drawn = primitive._indices
        if shadow:
            primitive._indices = primitive.point_all_indices
        if per_sample:
            glEnable(GL_SAMPLE_SHADING)
            glMinSampleShading(1.0)
        sub_pixel = blend and getattr(primitive, "point_px_max", np.inf) < 1.5
        blend = blend and (sub_pixel or len(primitive.indices) <= 2 * BLEND_MAX_POINTS)
        try:
            if not sub_pixel:  # (else the solid part is empty)
                _bind_sphere_uniforms(program, primitive, SPHERE_SOLID if blend else SPHERE_EXACT, shadow)
                super()._bind_and_draw_primitive(primitive, pose, program, flags)
            if blend:
                # the fringe over what is drawn (the cloud is drawn after the opaque objects: translate.py), not
                # writing depth; pyrender blends a "BLEND" material (alpha "over" during render_color); spheres
                # all under 1.5 px as GL points
                fringe = point_sprites(primitive) if sub_pixel else primitive
                _bind_sphere_uniforms(program, fringe, SPHERE_FRINGE, False)
                material, alpha_mode = primitive.material, primitive.material.alphaMode
                material.alphaMode = "BLEND"
                glDepthMask(False)
                try:
                    super()._bind_and_draw_primitive(fringe, pose, program, flags)
                finally:
                    material.alphaMode = alpha_mode
                    glDepthMask(True)
        finally:
            primitive._indices = drawn
            if per_sample:
                glDisable(GL_SAMPLE_SHADING)

    # -- clouds of sub-pixel spheres, splatted ----------------------------------------------------------
    def splat_layout(self, n: int) -> tuple[int, int] | None:
        """(width, height) of a texture of ``n`` texels, row by row (SPLAT_WIDTH a row); None when it exceeds the
        driver's texture size."""
        width = min(SPLAT_WIDTH, self.max_texture_size, max(n, 1))
        height = max(1, -(-n // width))
        return None if height > self.max_texture_size else (width, height)

    def _splat_inputs(self, primitive: Any) -> tuple[Any, Any]:
        """A cloud's shading quad (its attributes laid out as the cloud's, so that the cloud's program draws it)
        and the texture of its spheres (centre, diameter; object units) in splat order (_splat_order); made on
        first use, freed with the cloud (:meth:`free_splat_inputs`)."""
        key = id(primitive)
        hit = self._splat_inputs_of.get(key)
        if hit is not None and hit[0] is primitive:
            return hit[1], hit[2]
        n = len(primitive.point_all_indices) // 2
        layout = self.splat_layout(n)
        if layout is None:  # _thin_clouds checks it first
            raise RenderError(f"pyrender: a cloud of {n} points exceeds the shading target's size")
        width, height = layout
        order = _splat_order(primitive)
        centres = np.zeros((width * height, 4), dtype=np.float32)
        centres[:n, :3] = primitive.positions[0 : 4 * n : 4][order]
        centres[:n, 3] = primitive.texcoord_0[0 : 4 * n : 4, 0][order]
        points = _FloatTexture(centres.reshape(height, width, 4), nearest=True)
        quad = pyrender.Primitive(
            positions=np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float32),
            texcoord_0=np.zeros((4, 2), dtype=np.float32),
            # white: the spheres' own colours multiply the shaded colour later (splat_points), as COLOR_0 does
            color_0=None if primitive.color_0 is None else np.ones((4, 4), dtype=np.float32),
            indices=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32),
            material=primitive.material,
            mode=GLTF.TRIANGLES,
        )
        quad._add_to_context()
        self.free_splat_inputs(key)
        self._splat_inputs_of[key] = (primitive, quad, points)
        return quad, points

    def free_splat_inputs(self, key: int | None = None, keep: set[int] | None = None) -> None:
        """Free the shading inputs of one cloud (``key``), or of every cloud not in ``keep``."""
        keys = [key] if key is not None else [k for k in self._splat_inputs_of if k not in (keep or set())]
        for k in keys:
            entry = self._splat_inputs_of.pop(k, None)
            if entry is not None:
                entry[1]._remove_from_context()
                entry[2].delete()

    def _shade_points(self, primitive: Any, pose: Any, program: Any, flags: int) -> None:
        """Shade the spheres of a cloud, each as a whole (the BLENDIFY_POINT_SHADE program: one fragment per
        sphere, in a float target of its own; white, its colour applied by splat_points), one in every ``stride``
        of the splat order (at most SPLAT_SHADES_PER_PIXEL per pixel of the image: neighbours share it), and read
        the radiance back into ``splat_shades`` (summed over the passes of light groups), with the window depth
        of what the colour pass drew before the cloud (opaque surfaces, farther translucent ones) for
        splat_points' occlusion test. Draws nothing into the colour pass."""
        quad, points = self._splat_inputs(primitive)
        n = len(primitive.point_all_indices) // 2
        w, h = self._target[0], self._target[1]
        stride = max(1, -(-n // max(1, int(SPLAT_SHADES_PER_PIXEL * w * h))))
        shaded = -(-n // stride)
        layout = self.splat_layout(shaded)
        if layout is None:  # fewer than the cloud's points, which fit (_thin_clouds)
            raise RenderError(f"pyrender: {shaded} shaded spheres exceed the shading target's size")
        width, height = layout
        main = self._main_fb_ms
        glBindFramebuffer(GL_READ_FRAMEBUFFER, main)
        glPixelStorei(GL_PACK_ALIGNMENT, 1)
        depth = np.frombuffer(glReadPixels(0, 0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT), dtype=np.float32)
        depth = depth.reshape(h, w)[::-1]
        self._bind_texture(points, "bf_point_data", program)
        program.set_uniform("bf_point_layout", np.array([width, stride, n], dtype=np.int32))
        fb = self._framebuffer("points", width, height, 0)
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb["draw"])
        glViewport(0, 0, width, height)
        glDisable(GL_DEPTH_TEST)
        glDepthMask(False)
        glClearBufferfv(GL_COLOR, 0, np.zeros(4, dtype=np.float32))
        material, alpha_mode = quad.material, quad.material.alphaMode
        material.alphaMode = "OPAQUE"  # written as shaded (radiance, opacity), not blended over the target
        try:
            super()._bind_and_draw_primitive(quad, pose, program, flags)
            glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["read"])
            glReadBuffer(GL_COLOR_ATTACHMENT0)
            buf = glReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT)
            shade = np.frombuffer(buf, dtype=np.float32).reshape(-1, 4)[:shaded]
        finally:
            material.alphaMode = alpha_mode
            glBindFramebuffer(GL_FRAMEBUFFER, main)
            glViewport(0, 0, w, h)
            glEnable(GL_DEPTH_TEST)
            glDepthMask(True)
        prev = self.splat_shades.get(id(primitive))
        if prev is not None:  # a later light group's pass: its lights add up
            shade = shade.copy()
            shade[:, :3] += prev[2][:, :3]
        self.splat_shades[id(primitive)] = (primitive, np.asarray(pose, dtype=np.float64), shade, depth, stride)

    def sort_clouds(self, scene: Any, nodes: list[Any]) -> None:
        """Order the drawn points of each cloud of sub-pixel spheres (``point_px_max`` < 1.5, set per frame: drawn
        as GL points, :func:`point_sprites`) far to near in its element buffer: their blended coverage then
        composites front over back, as a path tracer sees them (unsorted, the points behind would weigh as
        much as those in front)."""
        self._update_context(scene, RenderFlags.NONE)
        cam = scene.get_pose(scene.main_camera_node)
        for node in nodes:
            if node is None:
                continue
            for prim in node.mesh.primitives:
                if not is_sphere_cloud(prim) or getattr(prim, "point_px_max", np.inf) >= 1.5:
                    continue
                if getattr(prim, "point_splat", False):
                    continue
                twin = point_sprites(prim)
                m = len(twin.indices)
                pose = scene.get_pose(node)
                centres = prim.positions[0 : 4 * m : 4].astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
                depth = (centres - cam[:3, 3]) @ -cam[:3, 2]
                order = np.argsort(-depth, kind="stable").astype(np.uint32)
                glBindBuffer(GL_COPY_WRITE_BUFFER, twin._buffers[-1])  # the element buffer (pyrender's last)
                glBufferSubData(GL_COPY_WRITE_BUFFER, 0, order.nbytes, order)
                glBindBuffer(GL_COPY_WRITE_BUFFER, 0)

    # -- shadow control --------------------------------------------------------------------------
    def _shadow_mapping_pass(self, scene: Any, light_node: Any, flags: int) -> None:
        key = self.shadow_key
        texture = light_node.light.shadow_texture
        if key is not None and self._shadow_done.get(light_node) == (key, id(texture)):
            return  # the map of this light is still valid (only the camera moved)
        self._shadow_light = light_node
        try:
            if any(n.mesh.is_visible for n in self._sorted_mesh_nodes(scene)):
                super()._shadow_mapping_pass(scene, light_node, flags)
            else:
                # nothing casts a shadow from this light: a cleared map (pyrender's pass draws nothing and
                # then fails on its unset shader program)
                self._configure_shadow_mapping_viewport(light_node.light, flags)
                glFlush()
        finally:
            self._shadow_light = None
        self._shadow_done[light_node] = (key, id(texture))

    def shadow_maps(self, scene: Any, flags: int) -> None:
        """Draw (or keep, while ``shadow_key`` holds) the shadow maps of the lights ``flags`` shadows, as
        pyrender's render does before its colour pass."""
        self._update_context(scene, flags)
        for ln in scene.light_nodes:
            light = ln.light
            if (isinstance(light, pyrender.DirectionalLight) and flags & RenderFlags.SHADOWS_DIRECTIONAL) or (
                isinstance(light, pyrender.SpotLight) and flags & RenderFlags.SHADOWS_SPOT
            ):
                self._shadow_mapping_pass(scene, ln, flags)

    def _sorted_mesh_nodes(self, scene: Any) -> list[Any]:
        nodes = super()._sorted_mesh_nodes(scene)
        if self._shadow_light is not None:
            if self._shadow_light in self.no_shadow_lights:
                return []  # an empty (cleared) shadow map: the light casts no shadow
            return [n for n in nodes if n not in self.no_shadow_nodes]
        return nodes

    # -- passes ----------------------------------------------------------------------------------
    def render_color(self, scene: Any, width: int, height: int, samples: int, flags: int) -> np.ndarray:
        """Lit colour pass, alpha = coverage x opacity, rows top to bottom (read-only): (H, W, 4) float32
        linear premultiplied radiance (``float_color``), else uint8 gamma 1/2.2 encoded (pyrender's shader;
        see :func:`color_pass_linear`); a scene with more lights of a type than pyrender binds per draw is
        rendered in groups of lights and summed (:meth:`light_groups`): float32 linear. pyrender blends
        translucent materials with glBlendFunc(SRC_ALPHA, ONE_MINUS_SRC_ALPHA), which also squares the
        destination alpha; during this call its blend function keeps alpha "over"-composited (ONE,
        ONE_MINUS_SRC_ALPHA) instead."""
        self.viewport_width, self.viewport_height = width, height
        self._target = (width, height, samples)
        flags |= RenderFlags.OFFSCREEN | RenderFlags.RGBA | RenderFlags.SKIP_CULL_FACES
        if samples == 0:
            glDisable(GL_MULTISAMPLE)
        groups = self.light_groups(scene, flags)
        original = _pyrender_renderer.glBlendFunc
        _pyrender_renderer.glBlendFunc = _blend_func_alpha_over
        try:
            if len(groups) == 1:
                color, _ = self.render(scene, flags)
            else:
                color = self._render_light_groups(scene, flags, groups)
        finally:
            _pyrender_renderer.glBlendFunc = original
        return color

    # -- lights beyond pyrender's per-draw limits ----------------------------------------------------
    def light_groups(self, scene: Any, flags: int) -> list[tuple[list[Any], list[Any], list[Any]]]:
        """The scene's (directional, spot, point) light nodes in groups that each fit the number of lights of a
        type bound per draw (``_compute_max_n_lights``: pyrender's 4, more for a shadowed type where texture
        units allow, a type without shadow maps up to ``MAX_UNSHADOWED_LIGHTS``). One group (all lights) when
        the scene fits or ``LIGHT_GROUPS`` is off; otherwise as many as the most demanding type needs, each type
        dealt round robin (lights in a fixed order: by pose)."""
        kinds = (scene.directional_light_nodes, scene.spot_light_nodes, scene.point_light_nodes)
        self._light_counts = (len(kinds[0]), len(kinds[1]), len(kinds[2]))
        max_n = self._compute_max_n_lights(flags)
        n = max([1] + [-(-len(k) // max(m, 1)) for k, m in zip(kinds, max_n)]) if LIGHT_GROUPS else 1
        if n == 1:
            return [(list(kinds[0]), list(kinds[1]), list(kinds[2]))]
        poses = {node: tuple(scene.get_pose(node).ravel()) for k in kinds for node in k}
        ordered = [sorted(k, key=poses.__getitem__) for k in kinds]
        return [(ordered[0][g::n], ordered[1][g::n], ordered[2][g::n]) for g in range(n)]

    def _compute_max_n_lights(self, flags: int) -> list[int]:
        """pyrender's lights of each type (directional, spot, point) per draw; a type without shadow maps in
        this pass and more lights than that in the scene (``light_groups`` counts them) takes up to
        ``MAX_UNSHADOWED_LIGHTS``, the next power of two above its count."""
        max_n: list[int] = super()._compute_max_n_lights(flags)
        if not LIGHT_GROUPS:
            return max_n
        shadows = (RenderFlags.SHADOWS_DIRECTIONAL, RenderFlags.SHADOWS_SPOT, RenderFlags.SHADOWS_POINT)
        for t, (count, shadow) in enumerate(zip(self._light_counts, shadows)):
            if count > max_n[t] and not flags & shadow:
                max_n[t] = min(MAX_UNSHADOWED_LIGHTS, 1 << (count - 1).bit_length())
        return max_n

    def _render_light_groups(self, scene: Any, flags: int, groups: list[Any]) -> np.ndarray:
        """The colour pass as the sum of one forward pass per light group (linear premultiplied float32). The
        shadow maps of all lights are drawn (or kept) first, as ``render`` does; the light that comes from no
        light node (the world's and the indirect-light probe's SH, the probe's map, emission) is in the first
        pass only. Every pass draws the same surfaces with the same alpha (coverage x opacity), and blending
        translucent surfaces is linear in radiance at a fixed alpha, so the radiance of the passes adds up to
        that of one pass with every light; alpha is the first pass's."""
        self.shadow_maps(scene, flags)
        attrs = ("_directional_light_nodes", "_spot_light_nodes", "_point_light_nodes")
        saved_nodes = [getattr(scene, a) for a in attrs]
        saved = (self.env_sh, self.spec_sh, self.emission_scale, self.probe_scale)
        grid = self.probe_grid
        total = np.zeros(0, dtype=np.float32)
        try:
            for g, group in enumerate(groups):
                for attr, nodes in zip(attrs, group):
                    setattr(scene, attr, set(nodes))
                if g == 1:
                    self.env_sh = self.spec_sh = np.zeros_like(saved[0])
                    self.emission_scale = self.probe_scale = 0.0
                    self.probe_grid = None  # its texture kept (grid)
                color, _ = self._forward_pass(scene, flags)
                if g == 0:
                    total = color_pass_linear(color)
                else:
                    total[..., :3] += color_pass_linear(color)[..., :3]
        finally:
            for attr, nodes in zip(attrs, saved_nodes):
                setattr(scene, attr, nodes)
            self.env_sh, self.spec_sh, self.emission_scale, self.probe_scale = saved
            self.probe_grid = grid
        return total

    def _draw_nodes(self, scene: Any, ids: dict[Any, int], shader: str, with_material: bool, full: bool) -> None:
        """Draw the visible mesh nodes in ``ids`` (node -> instance id) with one of our shader pairs (``full``:
        every point of a cloud at its own diameter, else the subset the colour pass draws)."""
        V, P = self._get_camera_matrices(scene)  # noqa: N806
        cam_pos = scene.get_pose(scene.main_camera_node)[:3, 3]
        program = None
        for node in scene.mesh_nodes:
            inst_id = ids.get(node)
            if inst_id is None or not node.mesh.is_visible:
                continue
            pose = scene.get_pose(node)
            for prim in node.mesh.primitives:
                if not full and id(prim) in self.coverage_skip:
                    continue
                defines = _buffer_defines(prim)
                sphere = is_sphere_cloud(prim)
                if sphere:
                    defines["BLENDIFY_SPHERE"] = 1
                tex = getattr(prim.material, "baseColorTexture", None) if with_material else None
                if tex is not None and "TEXCOORD_0_LOC" in defines:
                    defines["HAS_BASE_COLOR_TEX"] = 1
                program = self._program_cache.get_program(
                    vertex_shader=shader + ".vert", fragment_shader=shader + ".frag", defines=defines
                )
                if not program._in_context():
                    program._add_to_context()
                program._bind()
                program.set_uniform("V", V)
                program.set_uniform("P", P)
                program.set_uniform("M", pose)
                if with_material:
                    program.set_uniform("instance_id", float(inst_id + 1))
                    program.set_uniform("albedo_factor", np.asarray(prim.albedo_factor, dtype=np.float32))
                    if "HAS_BASE_COLOR_TEX" in defines:
                        self._bind_texture(tex, "base_color_texture", program)
                if with_material:
                    program.set_uniform("cam_pos", cam_pos)
                if sphere:
                    _bind_sphere_uniforms(program, prim, SPHERE_EXACT, full)
                prim._bind()
                n_inst = 1 if prim.poses is None else len(prim.poses)
                glDisable(GL_PROGRAM_POINT_SIZE)
                if prim.mode == GLTF.POINTS:
                    glPointSize(self.point_size)
                indices = prim.point_all_indices if sphere and full else prim.indices
                if indices is not None:
                    glDrawElementsInstanced(prim.mode, indices.size, GL_UNSIGNED_INT, ctypes.c_void_p(0), n_inst)
                else:
                    glDrawArraysInstanced(prim.mode, 0, len(prim.positions), n_inst)
                prim._unbind()
                self._reset_active_textures()
        if program is not None:
            program._unbind()

    def _begin_pass(self, width: int, height: int) -> None:
        glViewport(0, 0, width, height)
        glEnable(GL_DEPTH_TEST)
        glDepthMask(True)
        glDepthFunc(GL_LESS)
        glDisable(GL_CULL_FACE)
        glDisable(GL_BLEND)
        glPolygonMode(GL_FRONT_AND_BACK, GL_FILL)
        self.viewport_width, self.viewport_height = width, height

    def render_gbuffer(self, scene: Any, width: int, height: int, ids: dict[Any, int]) -> GBuffer:
        """Draw the mesh nodes in ``ids`` (node -> instance id) into the float G-buffer, one sample per
        pixel centre, both faces."""
        self._update_context(scene, RenderFlags.NONE)
        fb = self._framebuffer("gbuffer", width, height, 0)
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb["draw"])
        glDrawBuffers(2, [GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1])
        zero = np.zeros(4, dtype=np.float32)
        glClearBufferfv(GL_COLOR, 0, zero)
        glClearBufferfv(GL_COLOR, 1, zero)
        glClear(GL_DEPTH_BUFFER_BIT)
        glDisable(GL_MULTISAMPLE)
        self._begin_pass(width, height)
        self._draw_nodes(scene, ids, "blendify_gbuffer", True, True)
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["read"])
        out = []
        for att in (GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1):
            glReadBuffer(att)
            buf = glReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT)
            out.append(np.frombuffer(buf, dtype=np.float32).reshape(height, width, 4)[::-1])
        glBindFramebuffer(GL_FRAMEBUFFER, 0)
        return GBuffer(out[0], out[1])

    def render_coverage(self, scene: Any, width: int, height: int, samples: int, ids: dict[Any, int]) -> np.ndarray:
        """(H, W) float32 coverage of the nodes in ``ids`` from a ``samples``-times multisampled pass with a
        trivial shader (cheap even where the driver shades every sample, as llvmpipe does)."""
        self._update_context(scene, RenderFlags.NONE)
        fb = self._framebuffer("coverage", width, height, samples)
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb["draw"])
        glClearColor(0.0, 0.0, 0.0, 0.0)
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT)
        glEnable(GL_MULTISAMPLE)
        self._begin_pass(width, height)
        self._draw_nodes(scene, ids, "blendify_coverage", False, False)
        if samples > 0:
            glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["draw"])
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fb["read"])
            glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST)
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fb["read"])
        glReadBuffer(GL_COLOR_ATTACHMENT0)
        glPixelStorei(GL_PACK_ALIGNMENT, 1)
        buf = glReadPixels(0, 0, width, height, GL_RED, GL_UNSIGNED_BYTE)
        glBindFramebuffer(GL_FRAMEBUFFER, 0)
        return np.frombuffer(buf, dtype=np.uint8).reshape(height, width)[::-1].astype(np.float32) / 255.0


class MatrixCamera(pyrender.Camera):
    """A pyrender camera with an explicit OpenGL projection matrix (see ``CameraBuild`` in translate.py).
    The matrix does not depend on the viewport size as long as the viewport is the camera resolution
    times an integer (supersampling)."""

    def __init__(self, projection: np.ndarray, znear: float, zfar: float) -> None:
        super().__init__(znear=znear, zfar=zfar)
        self.projection = np.asarray(projection, dtype=np.float64)

    def get_projection_matrix(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        return self.projection


# ---------------------------------------------------------------------------------------------------
# pixels: linearisation, coverage, downsampling
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AntiAliasing:
    """How the colour pass is anti-aliased: ``mode`` "none", "coverage" (plain shading + multisampled
    coverage), "msaa" (multisampled shading) or "ssaa" (supersampling by ``supersample``)."""

    mode: str
    msaa: int = 0
    supersample: int = 1

    def describe(self) -> dict[str, Any]:
        return {"mode": self.mode, "msaa": self.msaa, "supersample": self.supersample}


def color_pass_linear(img: np.ndarray) -> np.ndarray:
    """A colour pass (:meth:`FrameRenderer.render_color`) as linear premultiplied float32 (H, W, 4), writable:
    the float pass as read (the MSAA resolve and the blending already average linear, premultiplied values),
    the 8-bit fallback through :func:`linearise_rgba8`."""
    if img.dtype == np.uint8:
        return linearise_rgba8(img)
    return np.array(img, dtype=np.float32, order="C")


def linearise_rgba8(img: np.ndarray) -> np.ndarray:
    """pyrender's 8-bit colour (gamma 1/2.2, premultiplied by coverage when multisampled) to linear
    premultiplied float32: straight = C / A, linear = straight^2.2, times A (a table for opaque pixels)."""
    h, w = img.shape[:2]
    out = np.empty((h, w, 4), dtype=np.float32)
    for c in range(3):
        np.take(_LIN8, img[..., c], out=out[..., c])
    np.take(_ALPHA8, img[..., 3], out=out[..., 3])
    a8 = img[..., 3]
    partial = (a8 > 0) & (a8 < 255)
    if np.any(partial):
        a = out[..., 3][partial][:, None]
        c = img[..., :3][partial].astype(np.float32) / 255.0
        straight = np.clip(c / a, 0.0, 1.0)
        out[partial, :3] = (straight**_GAMMA) * a
    return out


def apply_coverage(rgba: np.ndarray, coverage: np.ndarray, own: np.ndarray | None = None) -> np.ndarray:
    """Anti-aliased silhouettes from a plain (one sample per pixel) colour pass and a supersampled
    coverage. The plain pass gives each pixel's straight colour and opacity (alpha < 1 only for
    translucent materials); pixels whose centre missed every surface take the mean of their covered
    8-neighbours; the output alpha is coverage x opacity (premultiplied colour). Pixels in ``own`` (H, W)
    keep the plain pass's straight colour and take ``OWN_WEIGHT`` of their alpha from it (it blended them by
    their coverage: point clouds; a translucent material's pixels among them lose some of the coverage of
    their silhouette)."""
    opacity = rgba[..., 3].copy()
    hit = opacity > 0
    h, w = hit.shape
    straight = np.zeros((h, w, 3), dtype=np.float32)
    np.divide(rgba[..., :3], opacity[..., None], out=straight, where=hit[..., None])
    cov = coverage.astype(np.float32, copy=True)
    ys, xs = np.nonzero((~hit) & (cov > 0))
    if len(ys):
        acc = np.zeros((len(ys), 4), dtype=np.float32)
        cnt = np.zeros(len(ys), dtype=np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy == 0 and dx == 0:
                    continue
                yy, xx = ys + dy, xs + dx
                ok = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
                yy, xx = np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)
                m = ok & hit[yy, xx]
                acc[m, :3] += straight[yy[m], xx[m]]
                acc[m, 3] += opacity[yy[m], xx[m]]
                cnt += m
        mean = acc / np.maximum(cnt, 1.0)[:, None]
        straight[ys, xs] = mean[:, :3]
        opacity[ys, xs] = mean[:, 3]
    alpha = cov * opacity
    out = np.empty_like(rgba)
    out[..., :3] = straight * alpha[..., None]
    out[..., 3] = alpha
    if own is not None:
        a_own = OWN_WEIGHT * rgba[..., 3][own] + (1.0 - OWN_WEIGHT) * cov[own]
        out[own, :3] = rgba[own, :3] / rgba[own, 3:4] * a_own[:, None]
        out[own, 3] = a_own
    return out


def splat_points(
    centres: np.ndarray,
    radii: np.ndarray,
    radiance: np.ndarray,
    opacity: np.ndarray,
    view: np.ndarray,
    proj: np.ndarray,
    width: int,
    height: int,
    depth: np.ndarray | None = None,
    layers: int = SPLAT_LAYERS,
) -> np.ndarray:
    """The premultiplied linear (H, W, 4) image of a cloud of sub-pixel spheres, each shaded as a whole:
    ``centres`` (3, N) and ``radii`` (N,) in the frame of ``view`` (model-view), ``radiance`` (3, N) linear,
    ``opacity`` (N,), ``proj`` the OpenGL projection (perspective or orthographic), ``depth`` (H, W, rows top to
    bottom) the window depth of what hides the spheres (None: nothing).

    A sphere covers the square of its projected area around its projected centre (as the blended spheres of the
    colour pass, shaders/blendify_sphere_frag.glsl), so the fraction ``w`` of a pixel it covers is the square's
    overlap with the pixel, times its opacity (a square under SPLAT_ONE_TAP px wide counts whole in the pixel of its
    centre). The cloud's depth range is cut into ``layers`` slabs; per pixel and slab: colour = the w-weighted mean
    radiance of the spheres in it, alpha = 1 - prod(1 - w) (independent spheres: a single one covers its fraction,
    many small ones 1 - exp(-their summed fractions), a path tracer's coverage); the slabs are composited front to
    back (within a slab the order of the spheres is ignored). A sphere whose centre lies behind ``depth`` at its
    pixel is hidden."""
    m = (np.asarray(proj, dtype=np.float64) @ np.asarray(view, dtype=np.float64)).astype(np.float32)
    x, y, z = (np.asarray(c, dtype=np.float32) for c in centres)
    cw = m[3, 0] * x + m[3, 1] * y + m[3, 2] * z + m[3, 3]
    cz = m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3]
    keep = (cw > 1e-12) & (np.abs(cz) <= cw)  # in front of the camera, between the clipping planes
    inv = np.divide(np.float32(1.0), cw, out=np.zeros_like(cw), where=keep)
    u = (m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3]) * inv
    u = u * np.float32(0.5 * width) + np.float32(0.5 * width)
    v = (m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3]) * inv
    v = np.float32(0.5 * height) - v * np.float32(0.5 * height)  # rows top to bottom
    # half the side of the square of the disc's area (pixels): sqrt(pi)/2 x the radius r f / w
    s = np.asarray(radii, dtype=np.float32) * inv * np.float32(0.25 * np.sqrt(np.pi) * proj[0][0] * width)
    keep &= (u + s > 0) & (u - s < width) & (v + s > 0) & (v - s < height)
    if depth is not None:
        d = cz * inv * np.float32(0.5) + np.float32(0.5)
        ix = np.clip(u, 0, width - 1).astype(np.int32)
        iy = np.clip(v, 0, height - 1).astype(np.int32)
        keep &= d < depth[iy, ix]
    channels = [np.asarray(c, dtype=np.float32) for c in radiance]
    opacity = np.asarray(opacity, dtype=np.float32)
    lin = cw if proj[3][2] != 0.0 else cz  # linear in the view depth (perspective: w; orthographic: z)
    if not keep.all():
        u, v, s, opacity, lin = u[keep], v[keep], s[keep], opacity[keep], lin[keep]
        channels = [c[keep] for c in channels]
    size = width * height
    smax = float(s.max()) if s.size else 0.0
    one_tap = 2.0 * smax < SPLAT_ONE_TAP
    two_taps = not one_tap and smax <= 0.5  # squares of a pixel or less: on a grid padded by a pixel all round
    gw, gh = (width + 2, height + 2) if two_taps else (width, height)
    grid = gw * gh
    # the depth slab of each sphere: its first cell index
    slab = np.zeros(u.size, dtype=np.int32)
    if u.size and layers > 1:
        lo, hi = float(lin.min()), float(lin.max())
        if hi > lo:
            slab = np.minimum(((lin - lo) * np.float32(layers / (hi - lo))).astype(np.int32), layers - 1) * grid
    else:
        layers = 1
    acc = np.zeros((5, layers * grid), dtype=np.float64)  # sum w, sum w rgb, sum log(1 - w)

    def add(idx: np.ndarray, w: np.ndarray) -> None:
        idx = idx + slab
        acc[0] += np.bincount(idx, weights=w, minlength=layers * grid)
        for c in range(3):
            acc[1 + c] += np.bincount(idx, weights=w * channels[c], minlength=layers * grid)
        acc[4] += np.bincount(idx, weights=np.log1p(-np.minimum(w, np.float32(0.9999))), minlength=layers * grid)

    if s.size and one_tap:
        col = np.minimum(u.astype(np.int32), width - 1)  # u > -s > -1: truncation gives 0 left of the image
        row = np.minimum(v.astype(np.int32), height - 1)
        add(row * width + col, np.minimum(4.0 * s * s, np.float32(1.0)) * opacity)
    elif s.size and two_taps:
        # the square overlaps columns x0, x0 + 1 and rows y0, y0 + 1 (x0 >= -1, x0 + 1 <= W: inside the padding)
        x0, y0 = np.floor(u - s), np.floor(v - s)
        ox0 = np.minimum(u + s, x0 + 1.0) - (u - s)
        oy0 = np.minimum(v + s, y0 + 1.0) - (v - s)
        ox1, oy1 = 2.0 * s - ox0, 2.0 * s - oy0
        ox0, ox1 = ox0 * opacity, ox1 * opacity
        base = (y0.astype(np.int32) + 1) * gw + x0.astype(np.int32) + 1
        add(base, ox0 * oy0)
        add(base + 1, ox1 * oy0)
        add(base + gw, ox0 * oy1)
        add(base + (gw + 1), ox1 * oy1)
    elif s.size:
        x0, y0 = np.floor(u - s), np.floor(v - s)
        # overlaps of the square with the columns x0, x0 + 1, x0 + 2 (wider than a pixel) and the rows
        ox, oy = [], []
        for lo, c0, o in ((u - s, x0, ox), (v - s, y0, oy)):
            hi = lo + 2.0 * s
            for k in range(3):
                o.append(np.clip(np.minimum(hi, c0 + (k + 1)) - np.maximum(lo, c0 + k), 0.0, 1.0))
        x0i, y0i = x0.astype(np.int32), y0.astype(np.int32)
        for j in range(3):
            row = y0i + j
            row_ok = (row >= 0) & (row < height)
            for i in range(3):
                col = x0i + i
                ok = row_ok & (col >= 0) & (col < width)
                add(np.where(ok, row * width + col, 0), np.where(ok, ox[i] * oy[j] * opacity, np.float32(0.0)))
    acc = acc.reshape(5, layers, gh, gw)
    if two_taps:
        acc = acc[:, :, 1:-1, 1:-1]
    acc = acc.reshape(5, layers, size)
    alpha = 1.0 - np.exp(acc[4])  # per slab
    behind = np.cumprod(1.0 - alpha, axis=0)  # light through the slabs up to each one, front first
    seen = alpha.copy()
    seen[1:] *= behind[:-1]
    scale = np.divide(seen, acc[0], out=np.zeros_like(seen), where=acc[0] > 0)
    out = np.zeros((height, width, 4), dtype=np.float32)
    for c in range(3):
        out[..., c] = (acc[1 + c] * scale).sum(axis=0).reshape(height, width)
    # rounding in the overlaps and logarithms leaves a hair outside [0, 1] (-5e-12 for spheres of 1e-7 m)
    out[..., 3] = np.clip(1.0 - behind[-1], 0.0, 1.0).reshape(height, width)
    np.maximum(out[..., :3], 0.0, out=out[..., :3])
    return out


def box_downsample(img: np.ndarray, k: int) -> np.ndarray:
    if k == 1:
        return img
    h, w = img.shape[0] // k, img.shape[1] // k
    return img.reshape(h, k, w, k, *img.shape[2:]).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)


# ---------------------------------------------------------------------------------------------------
# one frame
# ---------------------------------------------------------------------------------------------------


def _shadow_flags(frame: Frame) -> int:
    """pyrender's shadow flags for the lights that cast shadows (when some object casts one)."""
    casters = any(e.casts_shadow and e.node is not None for e in frame.entries)
    flags = 0
    if not casters:
        return flags
    for node, _light, casts in frame.light_nodes:
        if not casts:
            continue
        if isinstance(node.light, pyrender.DirectionalLight):
            flags |= RenderFlags.SHADOWS_DIRECTIONAL
        elif isinstance(node.light, pyrender.SpotLight):
            flags |= RenderFlags.SHADOWS_SPOT
    return flags


def _thin_clouds(scene: Any, frame: Frame, splat: FrameRenderer | None = None) -> list[str]:
    """Choose how many points of each cloud the colour passes draw (the G-buffer and the shadow maps draw
    all): at most ``POINTS_PER_PIXEL`` points per covered pixel (a prefix of the randomly ordered points,
    never fewer than ``POINTS_MIN_DRAWN``), all of them when the cloud is not that dense; a cloud of spheres
    under ``SUBPIXEL_DRAWN_DIAMETER`` pixels is thinned to spheres of about that size, and a thinned cloud of
    sub-pixel spheres draws them larger by sqrt(all / drawn) (same summed area, same coverage). With ``splat``
    (the renderer, when the frame's colour pass splats) a cloud of spheres all under 1.5 px is marked
    ``point_splat``: its colour comes from every point (the thinned subset is what the light probes draw).
    Returns the notes (approximations) of the thinned clouds."""
    cam = frame.camera
    eye = scene.get_pose(scene.main_camera_node)[:3, 3]
    notes: list[str] = []
    for node in frame.nodes:
        if node is None:
            continue
        for prim in node.mesh.primitives:
            d = getattr(prim, "point_diameter", None)
            if d is None:
                continue
            centre = scene.get_pose(node)[:3, 3]
            px, extent_px = cam.screen_size(d, centre), cam.screen_size(prim.point_extent, centre)
            n = len(prim.point_all_indices) // 2  # two triangles per point
            # the largest sphere at the cloud's nearest point: are all spheres under 1.5 px (blended whole)?
            toward = eye - centre
            dist = float(np.linalg.norm(toward))
            near = centre + toward / max(dist, 1e-30) * min(prim.point_extent, 0.999 * dist)
            px_max = cam.screen_size(prim.point_diameter_max, near)
            # every sphere shaded once and splatted (FrameRenderer._shade_points)
            prim.point_splat = splat is not None and px_max < 1.5 and splat.splat_layout(n) is not None
            area = min(np.pi * extent_px**2, float(cam.width * cam.height))
            if px < SUBPIXEL_DRAWN_DIAMETER:
                # sub-pixel spheres each cost a whole pixel's shading: draw fewer, larger ones
                m = int(min(n, np.ceil(n * (px / SUBPIXEL_DRAWN_DIAMETER) ** 2)))
            else:
                m = int(min(n, max(POINTS_MIN_DRAWN, np.ceil(POINTS_PER_PIXEL * area / max(px, 1.0) ** 2))))
            if not prim._in_context():
                m = n  # the element buffer is uploaded from the current indices: upload all of them
            prim._indices = prim.point_all_indices[: 2 * m]  # the element buffer holds all; draw a prefix
            # a sub-pixel sphere covers a pixel with probability ~ its area: the drawn ones are enlarged so that
            # the thinned cloud keeps the summed area (and so the coverage) of the whole cloud
            prim.sphere_scale = float(np.sqrt(n / m)) if px < 1.0 else 1.0
            prim.point_px = px * prim.sphere_scale
            prim.point_px_max = px_max * prim.sphere_scale
            if m < n and not prim.point_splat and px < 1.0:
                notes.append(
                    f"pointcloud: colour from {m} of {n} points (sub-pixel spheres: a random subset, drawn "
                    f"{prim.sphere_scale:.2g}x wider so that it covers what the whole cloud does; depth, normal "
                    "and instance from every point)"
                )
            elif m < n and not prim.point_splat:
                notes.append(
                    f"pointcloud: colour from {m} of {n} points (a random subset: about {POINTS_PER_PIXEL} "
                    "points per covered pixel at this view; depth, normal and instance from every point)"
                )
    return notes


def _color(engine: Engine, frame: Frame, w: int, h: int, aa: AntiAliasing, flags: int) -> np.ndarray:
    """Linear premultiplied (H, W, 4) colour with the anti-aliasing scheme ``aa``."""
    r, scene = engine.renderer, engine.pscene
    if aa.mode in ("none", "coverage"):
        # the coverage scheme: point clouds' edges and sub-pixel spheres blended by the fraction of each pixel
        # they cover in the colour pass (its alpha), or (clouds marked point_splat) shaded sphere by sphere and
        # splatted (splat_points)
        r.sphere_blend = aa.mode == "coverage"
        prims = [p for n in frame.nodes if n is not None for p in n.mesh.primitives]
        splats = {id(p) for p in prims if r.sphere_blend and getattr(p, "point_splat", False)}
        if r.sphere_blend:
            r.sort_clouds(scene, frame.nodes)
        for p in prims:  # made before the pass: making a texture rebinds the active unit (a light's shadow map)
            if id(p) in splats:
                r._splat_inputs(p)
        r.point_splat = bool(splats)
        r.splat_shades = {}
        try:
            rgba = color_pass_linear(r.render_color(scene, w, h, 0, flags))
        finally:
            r.sphere_blend = False
            r.point_splat = False
        if aa.mode == "coverage":
            ids = {node: i for i, node in enumerate(frame.nodes) if node is not None}
            # supersampled, not multisampled: llvmpipe's MSAA is 4x slower even for a trivial shader
            k = COVERAGE_SUPERSAMPLE
            r.coverage_skip = splats  # they bring their own coverage
            try:
                cov = box_downsample(r.render_coverage(scene, w * k, h * k, 0, ids), k)
            finally:
                r.coverage_skip = set()
            # pixels a cloud's blended spheres cover in part keep the colour pass's alpha (their coverage)
            own = None
            if any(is_sphere_cloud(p) for p in prims):
                own = (rgba[..., 3] > 0.0) & (rgba[..., 3] < 1.0)
            rgba = apply_coverage(rgba, cov, own=own)
        if r.splat_shades:
            rgba = _composite_splats(r, scene, rgba, w, h)
        return rgba
    if aa.mode == "msaa":
        return color_pass_linear(r.render_color(scene, w, h, aa.msaa, flags))
    k = max(1, aa.supersample)  # "ssaa"
    return box_downsample(color_pass_linear(r.render_color(scene, w * k, h * k, 0, flags)), k)


def _splat_order(prim: Any) -> np.ndarray:
    """The order in which a cloud's spheres are shaded and splatted (cached): along a Morton curve through its
    bounding box (10 bits an axis), so that neighbouring fragments of the shading pass look up neighbouring
    texels of the shadow maps (in the cloud's random order the look-ups thrash the texture caches: 2x slower)."""
    order = getattr(prim, "splat_order", None)
    if order is None:
        n = len(prim.point_all_indices) // 2
        p = np.asarray(prim.positions[0 : 4 * n : 4], dtype=np.float64)
        lo, hi = p.min(axis=0), p.max(axis=0)
        q = ((p - lo) / np.maximum(hi - lo, 1e-30) * 1023.0).astype(np.uint64)
        code = np.zeros(n, dtype=np.uint64)
        for bit in range(10):
            for axis in range(3):
                code |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
        order = prim.splat_order = np.argsort(code, kind="stable")
    return order  # type: ignore[no-any-return]


def _splat_spheres(prim: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """A cloud's sphere centres (3, N) and radii (N,) (float32 object units) and colours ((4, N) or None), in its
    splat order (cached)."""
    cached = getattr(prim, "splat_spheres", None)
    if cached is None:
        n = len(prim.point_all_indices) // 2
        order = _splat_order(prim)
        centres = np.ascontiguousarray(np.asarray(prim.positions[0 : 4 * n : 4], dtype=np.float32)[order].T)
        radii = 0.5 * np.asarray(prim.texcoord_0[0 : 4 * n : 4, 0], dtype=np.float32)[order]
        colours = None
        if prim.color_0 is not None:
            c = np.ones((n, 4), dtype=np.float32)
            c0 = np.asarray(prim.color_0[0 : 4 * n : 4], dtype=np.float32)[order]
            c[:, : c0.shape[1]] = c0
            colours = np.ascontiguousarray(c.T)
        cached = prim.splat_spheres = (centres, radii, colours)
    return cached  # type: ignore[no-any-return]


def _composite_splats(r: FrameRenderer, scene: Any, rgba: np.ndarray, w: int, h: int) -> np.ndarray:
    """The splatted clouds of the last colour pass (``r.splat_shades``) over the anti-aliased colour, the farthest
    cloud first: each sphere takes the shade of the sphere its stride shaded times its own colour (COLOR_0
    multiplies the shaded colour)."""
    view, proj = r._get_camera_matrices(scene)
    eye = scene.get_pose(scene.main_camera_node)[:3, 3]
    entries = sorted(r.splat_shades.values(), key=lambda e: -float(np.linalg.norm(e[1][:3, 3] - eye)))
    r.splat_shades = {}
    for prim, pose, shade, depth, stride in entries:
        centres, radii, colours = _splat_spheres(prim)
        n = radii.size
        per = np.ascontiguousarray(shade.T)
        if stride > 1:
            per = np.repeat(per, stride, axis=1)[:, :n]
        if colours is not None:
            per = per * colours
        scale = float(np.linalg.norm(pose[:3, 0]))  # as the shaders: the model matrix's first column
        hides = depth is not None and float(depth.min()) < 1.0  # (1: nothing drawn before the cloud)
        hidden_by = depth if hides else None
        layer = splat_points(centres, radii * scale, per[:3], per[3], view @ pose, proj, w, h, hidden_by, SPLAT_LAYERS)
        rgba = layer + (1.0 - layer[..., 3:4]) * rgba
    return rgba


def _indirect_probe(engine: Engine, frame: Frame, flags: int) -> tuple[np.ndarray, str]:
    """The indirect-light probe's coefficients (probe.py) for this frame's scene and its grid of probes (set
    on the renderer), cached while the geometry, lights and world stay the same."""
    from .probe import probe_sh

    r = engine.renderer
    key = (frame.shadow_key, r.env_sh.tobytes())
    if r.probe_cache is None or r.probe_cache[0] != key:

        def render_rgba(width: int, height: int) -> np.ndarray:
            return color_pass_linear(r.render_color(engine.pscene, width, height, 0, flags))

        sh, grid, note = probe_sh(engine, frame, flags, render_rgba)
        r.probe_cache = (key, sh.astype(np.float32), grid, note)
        r.set_probe_grid(grid)
    elif r.probe_grid is None and r.probe_cache[2] is not None:  # dropped by a frame without the probe
        r.set_probe_grid(r.probe_cache[2])
    return r.probe_cache[1], r.probe_cache[3]


def render_frame(engine: Engine, frame: Frame, settings: RenderSettings, aa: AntiAliasing) -> RenderResult:
    """Render the frame the session translated (``frame``) with the anti-aliasing ``aa``."""
    w, h = frame.camera.width, frame.camera.height
    timings: dict[str, float] = {"sync": frame.sync_seconds}
    approximations = list(frame.notes)
    engine.context.make_current()
    renderer, scene = engine.renderer, engine.pscene
    renderer.no_shadow_nodes = {e.node for e in frame.entries if not e.casts_shadow}
    renderer.no_shadow_lights = {node for node, _, casts in frame.light_nodes if not casts}
    renderer._program_cache.soft = any(
        casts and float(getattr(node.light, "blendify_soft", 0.0)) > 0.0 for node, _, casts in frame.light_nodes
    )
    splat = SPLAT and aa.mode == "coverage" and renderer.float_targets
    approximations += _thin_clouds(scene, frame, renderer if splat else None)
    clouds = [p for n in frame.nodes if n is not None for p in n.mesh.primitives if is_sphere_cloud(p)]
    renderer.free_splat_inputs(keep={id(p) for p in clouds if p.point_splat})
    if "rgb" in set(settings.outputs) and aa.mode == "coverage":
        if any(p.point_px_max < 1.5 and not p.point_splat for p in clouds):
            approximations.append(
                "pointcloud: spheres under 1.5 px are blended by the fraction of each pixel they cover, far to "
                "near, each shaded as a whole (at the point facing the eye, direct light x 2/3); colour only"
            )
        if any(p.point_splat for p in clouds):
            approximations.append(SPLAT_NOTE)
    renderer.shadow_key = (frame.shadow_key, "all")
    catchers = [(i, e.node) for i, e in enumerate(frame.entries) if e.node is not None and e.catcher]
    want = set(settings.outputs)
    kinds = [type(node.light).__name__ for node, _, _ in frame.light_nodes]
    if "rgb" in want and not renderer.float_color:
        approximations.append(
            "colour: 8-bit colour pass (this driver has no float render targets): radiance clipped at 1, dark "
            "values quantised (linearised with (x/255)^2.2)"
        )
    if not LIGHT_GROUPS and any(kinds.count(k) > 4 for k in set(kinds)):
        approximations.append("lights: pyrender shades at most 4 lights of each type (the nearest are used)")
    if "rgb" in want and aa.mode == "coverage":
        approximations.append(
            "anti-aliasing: coverage scheme (silhouettes against the background are anti-aliased from a "
            "supersampled coverage pass; edges between objects are not)"
        )
    result = RenderResult(instance_tags=list(frame.tags))
    flags = _shadow_flags(frame)
    renderer.lenses, notes = lenses(scene, frame.nodes, renderer.no_shadow_nodes)
    renderer._program_cache.caustic = CAUSTICS and len(renderer.lenses) > 0 and flags != 0
    if renderer._program_cache.caustic:
        approximations += notes + [CAUSTIC_NOTE]
    gbuf = None
    try:
        if want & {"depth", "normal", "albedo", "instance"} or catchers:
            t0 = time.perf_counter()
            ids = {node: i for i, node in enumerate(frame.nodes) if node is not None}
            gbuf = renderer.render_gbuffer(scene, w, h, ids)
            timings["gbuffer"] = time.perf_counter() - t0
        if "rgb" in want:
            world_sh = renderer.env_sh
            renderer.spec_sh = world_sh
            renderer.probe_scale = 1.0 if PROBE else 0.0
            if not PROBE:
                renderer.set_probe_grid(None)
            if PROBE:
                t0 = time.perf_counter()
                renderer.env_sh, note = _indirect_probe(engine, frame, flags)
                if note:
                    approximations.append(note)
                timings["probe"] = time.perf_counter() - t0
            try:
                t0 = time.perf_counter()
                rgba = _color(engine, frame, w, h, aa, flags)
                timings["color"] = time.perf_counter() - t0
                if catchers:
                    t0 = time.perf_counter()
                    rgba = _apply_catchers(engine, frame, rgba, gbuf, catchers, w, h, aa, flags)
                    timings["shadow_catcher"] = time.perf_counter() - t0
            finally:
                renderer.env_sh = world_sh
            if not settings.transparent_background:
                bg = np.clip(frame.ambient, 0, None).astype(np.float32)
                if frame.background is not None:  # an environment map, seen through each pixel
                    bg = frame.background()
                rgba[..., :3] += (1.0 - rgba[..., 3:4]) * bg
                rgba[..., 3] = 1.0
            result.rgba = rgba
    except RenderError:
        raise
    except Exception as exc:
        raise RenderError(f"pyrender: rendering failed ({type(exc).__name__}: {exc})") from exc
    if gbuf is not None:
        if "depth" in want:
            result.depth = gbuf.depth
        if "normal" in want:
            result.normal = gbuf.normal
        if "albedo" in want:
            result.albedo = gbuf.albedo
        if "instance" in want:
            result.instance = gbuf.instance
    result.meta.update(
        backend="pyrender",
        platform=engine.context.platform,
        gl_renderer=renderer.gl_renderer,
        antialiasing=aa.describe() if "rgb" in want else None,
        approximations=sorted(set(approximations)),
        timings=timings,
        rebuilt_renderables=frame.rebuilt,
    )
    if frame.ignored:
        result.meta["ignored"] = sorted(set(frame.ignored))
    return result


def _apply_catchers(
    engine: Engine,
    frame: Frame,
    rgba: np.ndarray,
    gbuf: Any,
    catchers: list[tuple[int, Any]],
    w: int,
    h: int,
    aa: AntiAliasing,
    flags: int,
) -> np.ndarray:
    """Shadow catchers: render the catchers alone (unoccluded light), then replace catcher pixels by
    black with alpha = 1 - shadowed / unshadowed luminance (Cycles' shadow-catcher compositing)."""
    catcher_nodes = {node for _, node in catchers}
    hidden = [n for n in engine.pscene.mesh_nodes if n not in catcher_nodes and n.mesh.is_visible]
    for n in hidden:
        n.mesh.is_visible = False
    key = engine.renderer.shadow_key
    engine.renderer.shadow_key = (key, "catchers")
    try:
        alone = _color(engine, frame, w, h, aa, flags)
    finally:
        for n in hidden:
            n.mesh.is_visible = True
        engine.renderer.shadow_key = key
    lum_w = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    inst = gbuf.instance
    catcher_ids = [i for i, _ in catchers]
    in_front = (inst >= 0) & ~np.isin(inst, catcher_ids)  # another object is the first hit
    region = (alone[..., 3] > 0) & ~in_front  # catcher pixels, including its anti-aliased edges

    def luminance(img: np.ndarray) -> np.ndarray:
        straight = np.divide(img[..., :3], img[..., 3:4], out=np.zeros_like(img[..., :3]), where=img[..., 3:4] > 0)
        return straight @ lum_w

    with_occ, without = luminance(rgba), luminance(alone)
    ratio = np.divide(with_occ, without, out=np.ones_like(with_occ), where=without > 1e-6)
    shadow_alpha = np.clip(1.0 - ratio, 0.0, 1.0) * alone[..., 3]
    out = rgba.copy()
    out[region, :3] = 0.0
    out[region, 3] = shadow_alpha[region]
    return out
