// blendify: light through solid glass (inserted before mesh.frag's main; compiled only in the BLENDIFY_CAUSTIC
// variant: frames with a transmissive solid and a light casting shadows). A point a light's shadow map hides
// receives, instead of nothing, the light the glass objects between let through: each glass object is a ball
// lens (its bounding sphere, render.py lenses), the light's beam through it traced in BF_LENS_ZONES equal-area
// rings of impact parameter (in the plane holding the light, the ball's centre and the point: refracted in and
// out with Snell's law, Schlick's Fresnel at both interfaces), each ring spread uniformly over the annulus it
// lands on at the point's distance behind the ball and softened by the image of the emitter (its angular radius
// times that distance). The sum is relative to the light's unblocked irradiance at the point, so the shadow
// factor becomes (1 - shadow) + shadow x caustic: the caustic lights only what the shadow map hides.
uniform vec4 bf_lens[BF_MAX_LENSES];    // xyz: centre; w: radius
uniform vec4 bf_lens_t[BF_MAX_LENSES];  // rgb: transmittance through the object (weight x tint); w: IOR of its focusing
uniform int bf_n_lenses;
uniform float bf_spot_size[MAX_SPOT_LIGHTS];         // emitter radius (m)
uniform float bf_dir_size[MAX_DIRECTIONAL_LIGHTS];  // tan(half angular diameter)
const int BF_LENS_ZONES = 8;

// where a ray of impact parameter b from a source s in front of a ball (radius r, centre at the origin, light
// travelling along +y; s = 0: at infinity) lands in the plane y = d: (radial position, cosine of incidence,
// distance from the exit point to the plane)
vec3 bf_lens_land(float b, float r, float eta, float s, float d)
{
    vec2 u0 = vec2(0.0, 1.0);
    vec2 p1 = vec2(b, -sqrt(max(r * r - b * b, 0.0)));
    if (s > 0.0) {
        float sphi = b / s;
        u0 = vec2(sphi, sqrt(max(1.0 - sphi * sphi, 0.0)));
        p1 = vec2(0.0, -s) + (s * u0.y - sqrt(max(r * r - b * b, 0.0))) * u0;
    }
    vec2 n1 = p1 / r;
    float ci = clamp(-dot(u0, n1), 0.0, 1.0);
    vec2 u1 = refract(u0, n1, 1.0 / eta);
    vec2 p2 = p1 - 2.0 * dot(p1, u1) * u1;
    vec2 u2 = refract(u1, -p2 / r, eta);
    if (dot(u2, u2) < 0.5 || u2.y < 0.05 || p2.y > d) {
        return vec3(1e6, ci, 0.0);  // turned back, or leaves the ball beyond the plane: lands nowhere near
    }
    return vec3(p2.x + u2.x * (d - p2.y) / u2.y, ci, d - p2.y);
}

// the area of a disk of radius a whose edge ramps linearly over [a - w, a + w] (weights 1 .. 0)
float bf_ramp_area(float a, float w)
{
    return a >= w ? PI * (a * a + w * w / 3.0) : PI * (a + w) * (a + w) * (a + w) / (6.0 * w);
}

// the light factor through the glass objects at this fragment for a light at src (at_infinity: src is the
// direction towards it) of angular radius tan_r as seen from a lens (or emitter radius size at finite distance)
vec3 bf_caustic(vec3 src, bool at_infinity, float size)
{
    vec3 sum = vec3(0.0);
    for (int j = 0; j < bf_n_lenses; j++) {
        vec3 c = bf_lens[j].xyz;
        float r = bf_lens[j].w;
        vec3 p = frag_position - c;
        if (dot(p, p) < 1.0201 * r * r) {
            continue;  // the glass itself
        }
        float s = at_infinity ? 0.0 : length(c - src);
        if (!at_infinity && s <= 1.0001 * r) {
            continue;  // the light inside the glass
        }
        vec3 a = at_infinity ? -normalize(src) : (c - src) / s;
        float d = dot(p, a);
        if (d <= 0.0) {
            continue;  // in front of the glass
        }
        float rho = length(p - d * a);
        float tan_r = at_infinity ? size : size / s;
        float eta = max(bf_lens_t[j].w, 1.0);
        float f0 = (eta - 1.0) / (eta + 1.0);
        f0 *= f0;
        float x0 = bf_lens_land(0.0, r, eta, s, d).x;
        float acc = 0.0;
        for (int k = 0; k < BF_LENS_ZONES; k++) {
            vec3 hi_hit = bf_lens_land(r * sqrt(float(k + 1) / float(BF_LENS_ZONES)) * 0.999, r, eta, s, d);
            vec3 mid = bf_lens_land(r * sqrt((float(k) + 0.5) / float(BF_LENS_ZONES)), r, eta, s, d);
            float t = 1.0 - (f0 + (1.0 - f0) * pow(1.0 - mid.y, 5.0));
            float w = tan_r * d + 0.01 * r;  // the emitter's image through the ball (and a floor against hard rings)
            float lo = x0 * hi_hit.x > 0.0 ? min(abs(x0), abs(hi_hit.x)) : 0.0;
            float hi = max(abs(x0), abs(hi_hit.x));
            float inner = lo > 0.0 ? clamp((lo + w - rho) / (2.0 * w), 0.0, 1.0) : 0.0;
            float weight = clamp((hi + w - rho) / (2.0 * w), 0.0, 1.0) - inner;
            float area = bf_ramp_area(hi, w) - (lo > 0.0 ? bf_ramp_area(lo, w) : 0.0);
            acc += t * t * weight / max(area, 1e-9);
            x0 = hi_hit.x;
        }
        // each ring carries pi r^2 / zones of the irradiance at the glass; the fragment's own irradiance is
        // (s / (s + d))^2 of that (the light's falloff, which the shading applied)
        float falloff = at_infinity ? 1.0 : (s + d) * (s + d) / (s * s);
        sum += bf_lens_t[j].rgb * (acc * PI * r * r / float(BF_LENS_ZONES) * falloff);
    }
    return sum;
}
