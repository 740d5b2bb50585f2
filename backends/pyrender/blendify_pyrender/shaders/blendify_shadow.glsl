// blendify: soft shadows of lights with a size (inserted before mesh.frag's main, after pyrender's shadow_calc).
// Percentage-closer soft shadows from the one shadow map each light has: a blocker search in the region of the
// map the emitter can be seen through from this point, the blockers' mean distance from the receiver's tangent
// plane, and the penumbra the emitter's size gives at that distance (similar triangles), filtered over that
// width. Every look-up compares against the receiver's tangent plane at the looked-up texel (receiver-plane
// depth bias: no self-shadowing over the wide regions). bf_spot_soft[i] = (emitter radius m, near, far,
// tan(half fov)) of a spot/area light's perspective map; bf_dir_soft[i] = (tan(half angular diameter), near,
// far, half width) of a sun's orthographic map. A size of 0: pyrender's 3x3 PCF (hard shadows). Compiled only in
// the BLENDIFY_SOFT variant (frames with a soft light).
#ifdef BLENDIFY_SOFT
uniform vec4 bf_spot_soft[MAX_SPOT_LIGHTS];
uniform vec4 bf_dir_soft[MAX_DIRECTIONAL_LIGHTS];
const int BF_BLOCKER_K = 4;
const int BF_FILTER_K = 7;
//: blockers closer than this fraction of the receiver's distance to the light are not searched for (spot maps)
const float BF_SEARCH_NEAR = 0.3;
//: the largest filter radius, in shadow-map uv units
const float BF_MAX_RADIUS = 0.08;
//: the largest depth slope (window depth per uv) of the receiver-plane bias
const float BF_MAX_SLOPE = 1000.0;
//: the normal offset of the look-up point, in shadow-map texels at its distance
const float BF_NORMAL_OFFSET = 1.5;

float bf_linear_depth(float z, vec4 s, bool persp)
{
    if (persp) {
        return 2.0 * s.y * s.z / ((s.z + s.y) - (2.0 * z - 1.0) * (s.z - s.y));
    }
    return s.y + z * (s.z - s.y);
}

vec2 bf_texel_centre(vec2 uv, float size)
{
    // the shadow map is sampled nearest: the depth it returns is the one at the texel's centre
    return (floor(uv * size) + 0.5) / size;
}

float bf_reference(vec3 lc, vec2 dz, vec2 uv)
{
    // the depth a look-up at uv is compared with: the receiver's tangent plane there, but no farther than the
    // receiver (what lies beyond it cannot occlude it; where the plane's extrapolation passes behind the light
    // it exceeds 1)
    return min(lc.z + dot(dz, uv - lc.xy), lc.z);
}

float bf_soft_shadow(mat4 light_matrix, sampler2D shadow_map, float nl, vec4 s, bool persp, vec3 n)
{
    if (s.x <= 0.0) {
        return shadow_calc(light_matrix, shadow_map, nl);
    }
    // normal offset: the look-up point leaves the surface by BF_NORMAL_OFFSET texels (its own surface, curving
    // away from the tangent plane, does not shadow it at grazing light)
    vec4 pc = light_matrix * vec4(frag_position.xyz, 1.0);
    float size = float(textureSize(shadow_map, 0).x);
    float texel_world = 2.0 * (persp ? pc.w * s.w : s.w) / size;
    pc = light_matrix * vec4(frag_position.xyz + n * (BF_NORMAL_OFFSET * texel_world), 1.0);
    vec3 lc = pc.xyz / pc.w * 0.5 + 0.5;
    if (lc.z > 1.0) {
        return 0.0;
    }
    float bias = max(0.005 * (1.0 - nl), 0.0005) / pc.w;
    // receiver-plane depth bias: each look-up at offset o compares against the depth of the surface's tangent
    // plane there (the surface does not shadow itself over the wide search and filter regions)
    vec3 ddx = dFdx(lc);
    vec3 ddy = dFdy(lc);
    float det = ddx.x * ddy.y - ddx.y * ddy.x;
    vec2 dz = abs(det) > 1e-12
        ? vec2(ddy.y * ddx.z - ddx.y * ddy.z, ddx.x * ddy.z - ddy.x * ddx.z) / det
        : vec2(0.0);
    dz = clamp(dz, vec2(-BF_MAX_SLOPE), vec2(BF_MAX_SLOPE));
    float d_r = bf_linear_depth(lc.z, s, persp);
    // world length -> uv: 1 / (2 d tan) at distance d (perspective), 1 / (2 half width) (orthographic)
    float search = persp
        ? s.x * (1.0 - BF_SEARCH_NEAR) / (2.0 * BF_SEARCH_NEAR * d_r * s.w)
        : s.x * max(d_r - s.y, 0.0) / (2.0 * s.w);
    float texel = 1.0 / size;
    search = clamp(search, texel, BF_MAX_RADIUS);
    float sum = 0.0;
    float count = 0.0;
    for (int a = 0; a < BF_BLOCKER_K; a++) {
        for (int b = 0; b < BF_BLOCKER_K; b++) {
            vec2 o = ((vec2(float(a), float(b)) + 0.5) * (2.0 / float(BF_BLOCKER_K)) - 1.0) * search;
            vec2 uv = lc.xy + o;
            float z = texture(shadow_map, uv).r;
            float z_ref = bf_reference(lc, dz, bf_texel_centre(uv, size));
            if (z < z_ref - bias) {
                // the blocker's distance from the receiver's plane (not from the receiver: tilted blockers
                // parallel to the receiver are as far from it everywhere)
                sum += bf_linear_depth(z_ref, s, persp) - bf_linear_depth(z, s, persp);
                count += 1.0;
            }
        }
    }
    if (count == 0.0) {
        return 0.0;
    }
    float d_b = max(d_r - sum / count, 1e-6);
    float radius = persp
        ? s.x * max(d_r - d_b, 0.0) / d_b / (2.0 * d_r * s.w)
        : s.x * max(d_r - d_b, 0.0) / (2.0 * s.w);
    radius = clamp(radius, 1.5 * texel, BF_MAX_RADIUS);
    float shadow = 0.0;
    for (int a = 0; a < BF_FILTER_K; a++) {
        for (int b = 0; b < BF_FILTER_K; b++) {
            vec2 o = ((vec2(float(a), float(b)) + 0.5) * (2.0 / float(BF_FILTER_K)) - 1.0) * radius;
            vec2 uv = lc.xy + o;
            shadow += bf_reference(lc, dz, bf_texel_centre(uv, size)) - bias > texture(shadow_map, uv).r ? 1.0 : 0.0;
        }
    }
    return shadow / float(BF_FILTER_K * BF_FILTER_K);
}
#endif
