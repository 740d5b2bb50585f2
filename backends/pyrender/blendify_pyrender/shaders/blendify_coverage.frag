#version 330 core
out vec4 frag_color;
// @BLENDIFY_SPHERE_FRAG@
void main()
{
#ifdef BLENDIFY_SPHERE
    bf_sphere_hit();  // a point of a cloud: pixel centres on the exact sphere
#endif
    frag_color = vec4(1.0);
}
