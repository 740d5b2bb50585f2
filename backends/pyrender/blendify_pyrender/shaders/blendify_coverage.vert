#version 330 core
// blendify coverage pass: positions only (the multisample resolve gives the coverage).
layout(location = 0) in vec3 position;
#ifdef TEXCOORD_0_LOC
layout(location = TEXCOORD_0_LOC) in vec2 texcoord_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;
uniform mat4 M;
uniform mat4 V;
uniform mat4 P;
// @BLENDIFY_SPHERE_VERT@
void main()
{
    gl_Position = P * V * M * inst_m * vec4(position, 1.0);
#ifdef BLENDIFY_SPHERE
    gl_Position = bf_sphere_corner(M * inst_m, position, texcoord_0.x, texcoord_0.y);
#endif
}
