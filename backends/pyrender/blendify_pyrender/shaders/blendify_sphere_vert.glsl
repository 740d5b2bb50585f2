// Point clouds as exact spheres (vertex side, BLENDIFY_SPHERE): every point is a quad of 4 vertices at the
// sphere's centre (texcoord_0 = (diameter in object units, corner 0..3)) that this function spreads over
// the sphere's projected bounding box in screen space (perspective or orthographic P; the tangent planes
// of the sphere through the eye bound it exactly), grown by bf_sphere_grow pixels; or (bf_sphere_sprite) one
// GL point whose square sprite covers that box (clouds of spheres of a few pixels: a quarter of the vertices). The fragment side
// (blendify_sphere_frag.glsl) intersects each pixel centre's ray with the sphere.
#ifdef BLENDIFY_SPHERE
#ifndef TEXCOORD_0_LOC
#error "BLENDIFY_SPHERE needs texcoord_0 (diameter, corner)"
#endif
uniform vec2 bf_viewport;        // viewport size in pixels
uniform float bf_sphere_scale;   // diameter factor (thinned clouds of sub-pixel spheres)
uniform float bf_sphere_grow;    // pixels added around the projected box
uniform float bf_sphere_sprite;  // 1: one GL point per sphere (a square sprite over the box), not a quad
flat out vec4 bf_sphere;         // view-space centre, radius
flat out vec3 bf_sphere_px;      // projected centre (window pixels), radius in pixels at the centre's depth

vec4 bf_sphere_corner(mat4 model, vec3 centre, float diameter, float corner)
{
    vec3 c = (V * (model * vec4(centre, 1.0))).xyz;
    float r = 0.5 * diameter * bf_sphere_scale * length(vec3(model[0]));
    bf_sphere = vec4(c, r);
    vec2 f = vec2(P[0][0], P[1][1]);
    vec2 lo, hi;
    float w = P[2][3] * c.z + P[3][3];
    if (P[2][3] != 0.0) {  // perspective: planes x = s t through the eye tangent to the sphere (t = -z)
        float t = -c.z;
        float k = t * t - r * r;
        if (t + r <= 0.0) {
            lo = hi = vec2(3.0);  // behind the eye: nothing
        } else if (k <= 1e-6 * t * t) {
            lo = vec2(-1.0);  // the eye inside (or in the tangent cone of) the sphere: the whole view
            hi = vec2(1.0);
        } else {
            vec2 e = r * sqrt(c.xy * c.xy + k);
            vec2 pp = vec2(P[2][0], P[2][1]);
            lo = f * (c.xy * t - e) / k - pp;
            hi = f * (c.xy * t + e) / k - pp;
        }
    } else {
        vec2 off = vec2(P[3][0], P[3][1]);
        lo = f * (c.xy - r) + off;
        hi = f * (c.xy + r) + off;
    }
    vec2 grow = 2.0 * bf_sphere_grow / bf_viewport;
    lo -= grow;
    hi += grow;
    vec4 cc = P * vec4(c, 1.0);
    float px_world = 2.0 * abs(w) / (f.x * bf_viewport.x);  // world size of a pixel at the centre's depth
    bf_sphere_px = vec3((0.5 * cc.xy / cc.w + 0.5) * bf_viewport, r / max(px_world, 1e-30));
    if (bf_sphere_sprite > 0.5) {
        gl_PointSize = max((hi.x - lo.x) * bf_viewport.x, (hi.y - lo.y) * bf_viewport.y) * 0.5;
        return vec4(0.5 * (lo + hi), 0.0, 1.0);
    }
    int k4 = int(corner + 0.5);
    vec2 ndc = vec2((k4 == 1 || k4 == 2) ? hi.x : lo.x, (k4 >= 2) ? hi.y : lo.y);
    return vec4(ndc, 0.0, 1.0);  // depth comes from the fragment (gl_FragDepth)
}
#endif
