#version 330 core
// blendify G-buffer pass. Attachment 0: world normal (facing the viewer) + planar depth;
// attachment 1: linear albedo + (instance id + 1). Background stays 0.
in vec3 g_world_position;
in vec3 g_world_normal;
in float g_view_depth;
in vec2 g_uv;
in vec4 g_color;

uniform vec4 albedo_factor;
uniform vec3 cam_pos;
uniform float instance_id;
#ifdef BLENDIFY_SPRITE
uniform mat4 V;
uniform mat4 P;
flat in float sprite_diam_px;
flat in float sprite_radius_world;
#endif
#ifdef HAS_BASE_COLOR_TEX
uniform sampler2D base_color_texture;
#endif

layout(location = 0) out vec4 out_geometry;
layout(location = 1) out vec4 out_surface;

vec3 decode_srgb(vec3 c)
{
    vec3 lo = c / 12.92;
    vec3 hi = pow((c + 0.055) / 1.055, vec3(2.4));
    return mix(lo, hi, step(vec3(0.04045), c));
}

void main()
{
    vec3 n = g_world_normal;
    float depth = g_view_depth;
#ifdef BLENDIFY_SPRITE
    // sphere impostor: pixel centres inside the projected disc, the sphere's normal and depth there
    vec2 q = (gl_PointCoord - 0.5) * max(sprite_diam_px, 1.0);
    float r = 0.5 * sprite_diam_px;
    if (dot(q, q) > r * r) { discard; }
    vec2 u = q / max(r, 1e-12);
    vec3 nv = vec3(u.x, -u.y, sqrt(max(1.0 - dot(u, u), 0.0)));
    n = normalize(transpose(mat3(V)) * nv);
    vec3 p = g_world_position + sprite_radius_world * n;
    vec4 view = V * vec4(p, 1.0);
    depth = -view.z;
    vec4 clip = P * view;
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
#else
    if (dot(n, n) < 1e-20) {
        // no normals (points drawn as screen-space squares): face the camera, as pyrender shades them
        n = normalize(cam_pos - g_world_position);
    } else {
        n = normalize(n);
        if (!gl_FrontFacing) {
            n = -n;
        }
    }
#endif
    vec3 albedo = albedo_factor.rgb * g_color.rgb;
#ifdef HAS_BASE_COLOR_TEX
    albedo *= decode_srgb(texture(base_color_texture, g_uv).rgb);
#endif
    out_geometry = vec4(n, depth);
    out_surface = vec4(albedo, instance_id);
}
