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
// @BLENDIFY_SPHERE_VERT@

void main()
{
    mat4 model = M * inst_m;
    vec4 world = model * vec4(position, 1.0);
    vec4 view = V * world;
    gl_Position = P * view;
    g_world_position = world.xyz;
    g_view_depth = -view.z;
#ifdef BLENDIFY_SPHERE
    gl_Position = bf_sphere_corner(model, position, texcoord_0.x, texcoord_0.y);
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
