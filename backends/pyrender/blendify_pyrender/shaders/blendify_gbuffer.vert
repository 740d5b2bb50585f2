#version 330 core
// blendify G-buffer pass: planar view depth, world normal, albedo inputs (one sample per pixel).
layout(location = 0) in vec3 position;
#ifdef NORMAL_LOC
layout(location = NORMAL_LOC) in vec3 normal;
#endif
#ifdef TEXCOORD_0_LOC
layout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;
#endif
#ifdef COLOR_0_LOC
layout(location = COLOR_0_LOC) in vec4 color_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 M;
uniform mat4 V;
uniform mat4 P;

out vec3 g_world_position;
out vec3 g_world_normal;
out float g_view_depth;
out vec2 g_uv;
out vec4 g_color;
#ifdef BLENDIFY_SPRITE
// sphere impostors: the sprite's size in pixels from the point's diameter (texcoord_0.x, world units)
uniform float sprite_viewport;
uniform float sprite_diameter_scale;
flat out float sprite_diam_px;
flat out float sprite_radius_world;
#endif

void main()
{
    mat4 model = M * inst_m;
    vec4 world = model * vec4(position, 1.0);
    vec4 view = V * world;
    gl_Position = P * view;
    g_world_position = world.xyz;
    g_view_depth = -view.z;
#ifdef BLENDIFY_SPRITE
    float d_world = texcoord_0.x * sprite_diameter_scale * length(vec3(model[0]));
    sprite_radius_world = 0.5 * d_world;
    sprite_diam_px = d_world * P[0][0] * 0.5 * sprite_viewport / gl_Position.w;
    gl_PointSize = max(sprite_diam_px, 1.0);
#endif
#ifdef NORMAL_LOC
    g_world_normal = mat3(transpose(inverse(model))) * normal;
#else
    g_world_normal = vec3(0.0);
#endif
#ifdef TEXCOORD_0_LOC
    g_uv = texcoord_0;
#else
    g_uv = vec2(0.0);
#endif
#ifdef COLOR_0_LOC
    g_color = color_0;
#else
    g_color = vec4(1.0);
#endif
}
