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
// @BLENDIFY_SPHERE_FRAG@
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
#ifdef BLENDIFY_SPHERE
    // a point of a cloud: the exact sphere at the pixel centre
    bf_sphere_hit();
    n = bf_sphere_normal;
    depth = bf_sphere_depth;
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
