#version 330 core
out vec4 frag_color;
// @BLENDIFY_SPHERE_FRAG@
void main()
{
    float cover = 1.0;
#ifdef BLENDIFY_SPHERE
    // a point of a cloud: pixel centres on the exact sphere (mode 0), or the covered fraction (mode 2)
    bf_sphere_hit();
    cover = bf_sphere_cover;
#endif
    frag_color = vec4(cover);
}
