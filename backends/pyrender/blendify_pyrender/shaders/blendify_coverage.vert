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
#ifdef BLENDIFY_SPRITE
// sphere impostors: the sprite's size in pixels from the point's diameter (texcoord_0.x, world units)
uniform float sprite_viewport;
uniform float sprite_diameter_scale;
flat out float sprite_diam_px;
#endif
void main()
{
    gl_Position = P * V * M * inst_m * vec4(position, 1.0);
#ifdef BLENDIFY_SPRITE
    float d_world = texcoord_0.x * sprite_diameter_scale * length(vec3((M * inst_m)[0]));
    sprite_diam_px = d_world * P[0][0] * 0.5 * sprite_viewport / gl_Position.w;
    gl_PointSize = max(sprite_diam_px, 1.0);
#endif
}
