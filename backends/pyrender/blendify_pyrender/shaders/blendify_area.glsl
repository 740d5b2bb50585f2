// blendify: area lights for pyrender's mesh.frag (inserted before its main()).
// An area light is one of pyrender's spot lights (its shadow map, its place in the light arrays) whose
// bf_area_u[i].w is 1 (rectangle) or 2 (ellipse): its light is integrated over the emitting surface with a
// BF_AREA_K x BF_AREA_K midpoint rule (equal-area cells; the concentric map for ellipses), each point a
// cosine (Lambertian) emitter of radiance intensity x colour along the spot's direction (Blender's -Z).
uniform vec4 bf_area_u[MAX_SPOT_LIGHTS];  // xyz: local x axis x half size; w: 0 spot, 1 rectangle, 2 ellipse
uniform vec4 bf_area_v[MAX_SPOT_LIGHTS];  // xyz: local y axis x half size
const int BF_AREA_K = 6;

vec2 bf_concentric(vec2 s)
{
    // Shirley-Chiu: the square [-1, 1]^2 onto the unit disk, preserving relative areas
    if (s.x == 0.0 && s.y == 0.0) {
        return vec2(0.0);
    }
    float r;
    float phi;
    if (abs(s.x) > abs(s.y)) {
        r = s.x;
        phi = (PI / 4.0) * (s.y / s.x);
    } else {
        r = s.y;
        phi = (PI / 2.0) - (PI / 4.0) * (s.x / s.y);
    }
    return r * vec2(cos(phi), sin(phi));
}

vec3 bf_area_light(int i, vec3 n, vec3 v, float roughness, float metallic, vec3 f0, vec3 c_diff, vec3 albedo)
{
    vec3 hu = bf_area_u[i].xyz;
    vec3 hv = bf_area_v[i].xyz;
    bool ellipse = bf_area_u[i].w > 1.5;
    float area = 4.0 * length(hu) * length(hv) * (ellipse ? PI / 4.0 : 1.0);
    vec3 le = spot_lights[i].intensity * spot_lights[i].color;
    vec3 dir = spot_lights[i].direction;
    vec3 sum = vec3(0.0);
    for (int a = 0; a < BF_AREA_K; a++) {
        for (int b = 0; b < BF_AREA_K; b++) {
            vec2 s = (vec2(float(a), float(b)) + 0.5) * (2.0 / float(BF_AREA_K)) - 1.0;
            if (ellipse) {
                s = bf_concentric(s);
            }
            vec3 d = spot_lights[i].position + s.x * hu + s.y * hv - frag_position;
            float d2 = max(dot(d, d), 1e-12);
            vec3 l = d * inversesqrt(d2);
            float cos_e = -dot(dir, l);
#ifdef BLENDIFY_POINT_SHADE
            if (cos_e > 0.0) {  // a sphere shaded as a whole: lit from any side (bf_sphere_phase)
#else
            if (cos_e > 0.0 && dot(n, l) > 0.0) {
#endif
                sum += compute_brdf(n, v, l, roughness, metallic, f0, c_diff, albedo, le * (cos_e / d2));
            }
        }
    }
    return sum * (area / float(BF_AREA_K * BF_AREA_K));
}

