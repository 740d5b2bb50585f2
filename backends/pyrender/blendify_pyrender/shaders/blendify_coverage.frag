#version 330 core
out vec4 frag_color;
#ifdef BLENDIFY_SPRITE
flat in float sprite_diam_px;
#endif
void main()
{
#ifdef BLENDIFY_SPRITE
    // sphere impostor: pixel centres inside the projected disc only
    vec2 q = (gl_PointCoord - 0.5) * max(sprite_diam_px, 1.0);
    if (dot(q, q) > 0.25 * sprite_diam_px * sprite_diam_px) { discard; }
#endif
    frag_color = vec4(1.0);
}
