// blendify: the world's light from 9 spherical-harmonic coefficients (inserted before mesh.frag's main; replaces
// pyrender's uniform ambient term). bf_env_sh[k] = (A_l / pi) x L_lm, the cosine-convolved radiance
// coefficients (A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4): their sum with the basis is irradiance / pi.
uniform vec3 bf_env_sh[9];
// the world's light alone for the glossy term (bf_env_sh may hold the indirect-light probe's, probe.py)
uniform vec3 bf_spec_sh[9];
#ifdef BLENDIFY_PROBE_MAP
// what the indirect-light probe sees (probe.py), equirectangular, 8-bit gamma 2.2 times bf_probe_scale (0: none):
// metals reflect it (the scene around them) instead of the world's light
uniform sampler2D bf_probe_map;
uniform float bf_probe_scale;
// 1 when the probe was rendered from inside this object (its view is the object's surroundings)
uniform float bf_probe_inside;

// parallax: the map's surroundings taken to lie on the faces of the box bf_proxy_lo .. bf_proxy_hi (the scene's
// bounds), the map rendered from bf_probe_point; solid glass's exit ray (p, d) looks up the direction from the
// probe to where it leaves the box
uniform vec3 bf_probe_point;
uniform vec3 bf_proxy_lo;
uniform vec3 bf_proxy_hi;
uniform float bf_glass_radius;

vec3 bf_probe_parallax(vec3 p, vec3 d)
{
    vec3 dd = mix(d, vec3(1e-6), lessThan(abs(d), vec3(1e-6)));
    vec3 t = max((bf_proxy_lo - p) / dd, (bf_proxy_hi - p) / dd);
    vec3 q = p + max(min(min(t.x, t.y), t.z), 0.0) * d - bf_probe_point;
    return dot(q, q) > 1e-12 ? normalize(q) : d;
}

vec3 bf_probe_radiance(vec3 d, float roughness)
{
    vec2 uv = vec2(atan(d.y, d.x) / (2.0 * PI) + 0.5, 1.0 - acos(clamp(d.z, -1.0, 1.0)) / PI);
    float lod = roughness * log2(float(textureSize(bf_probe_map, 0).y));
    return pow(textureLod(bf_probe_map, uv, lod).rgb, vec3(2.2)) * bf_probe_scale;
}
#endif

vec3 bf_sh_of(vec3 s[9], vec3 d, vec3 band)
{
    // band: scale of bands 0, 1, 2 (1, 1, 1: irradiance / pi; 1, 1.5, 4: the radiance itself)
    vec3 c = s[0] * (0.282095 * band.x);
    c += (s[1] * d.y + s[2] * d.z + s[3] * d.x) * (0.488603 * band.y);
    c += (s[4] * (1.092548 * d.x * d.y) + s[5] * (1.092548 * d.y * d.z)
          + s[6] * (0.315392 * (3.0 * d.z * d.z - 1.0)) + s[7] * (1.092548 * d.x * d.z)
          + s[8] * (0.546274 * (d.x * d.x - d.y * d.y))) * band.z;
    return max(c, vec3(0.0));
}

#ifdef BLENDIFY_PROBE_GRID
// indirect light from a grid of probes (probe.py) at the centres of the nx x ny x nz cells of the box
// bf_grid_lo + [0, bf_grid_size]: coefficient k of probe (i, j, l) is texel (i, (k nz + l) ny + j) of bf_grid
uniform sampler2D bf_grid;
uniform vec3 bf_grid_lo;
uniform vec3 bf_grid_size;
uniform vec3 bf_grid_n;

vec3 bf_sh(vec3 d, vec3 band)
{
    // trilinear between the 8 nearest probes (clamped to the outer ones): bilinear filtering in x and y (the
    // row kept between the centres of a slab's first and last rows, so that it never mixes two slabs), linear
    // across the two nearest slabs in z (one look-up when there is one layer: a grid over a floor)
    vec3 t = clamp((frag_position - bf_grid_lo) / bf_grid_size * bf_grid_n, vec3(0.5), bf_grid_n - 0.5);
    float z0 = floor(t.z - 0.5);
    float fz = t.z - 0.5 - z0;
    float rows = 9.0 * bf_grid_n.z * bf_grid_n.y;
    vec2 uv0 = vec2(t.x / bf_grid_n.x, (z0 * bf_grid_n.y + t.y) / rows);
    vec2 dz = vec2(0.0, fz > 0.0 ? bf_grid_n.y / rows : 0.0);  // to the next layer
    vec2 dk = vec2(0.0, bf_grid_n.z * bf_grid_n.y / rows);  // to the next coefficient
    // the basis in direction d times the band scales (as bf_sh_of)
    float w[9] = float[9](0.282095 * band.x, 0.488603 * band.y * d.y, 0.488603 * band.y * d.z,
                          0.488603 * band.y * d.x, 1.092548 * band.z * d.x * d.y, 1.092548 * band.z * d.y * d.z,
                          0.315392 * band.z * (3.0 * d.z * d.z - 1.0), 1.092548 * band.z * d.x * d.z,
                          0.546274 * band.z * (d.x * d.x - d.y * d.y));
    vec3 c = vec3(0.0);
    for (int k = 0; k < 9; k++) {
        vec2 uv = uv0 + float(k) * dk;
        vec3 a = texture(bf_grid, uv).rgb;
        if (fz > 0.0) {
            a = mix(a, texture(bf_grid, uv + dz).rgb, fz);
        }
        c += a * w[k];
    }
    return max(c, vec3(0.0));
}
#else
vec3 bf_sh(vec3 d, vec3 band)
{
    return bf_sh_of(bf_env_sh, d, band);
}
#endif

vec3 bf_environment(vec3 n, vec3 v, float roughness, float metallic, vec3 f0, vec3 c_diff)
{
#ifdef BLENDIFY_POINT_SHADE
    // a sphere shaded as a whole (blendify_sphere_frag.glsl): the mean of the irradiance over the disc it shows,
    // its bands scaled by the disc's mean of P_l(n.v) (1, 2/3, 1/4)
    vec3 light = c_diff * bf_sh(n, vec3(1.0, 2.0 / 3.0, 0.25));
#else
    vec3 light = c_diff * bf_sh(n, vec3(1.0));
#endif
    if (roughness < 0.999 || metallic > 0.0) {  // a diffuse-only material (roughness 1, dielectric) has no lobe
        float nv = clamp(dot(n, v), 1e-4, 1.0);
        vec3 r = reflect(-v, n);
        // glossy lobe: the radiance in the mirror direction, blurred toward the irradiance with roughness
        vec3 band = mix(vec3(1.0, 1.5, 4.0), vec3(1.0), clamp(roughness, 0.0, 1.0));
        // split-sum environment BRDF, analytic fit (Karis 2014, "Physically Based Shading on Mobile")
        vec4 rc = roughness * vec4(-1.0, -0.0275, -0.572, 0.022) + vec4(1.0, 0.0425, 1.04, -0.04);
        float a004 = min(rc.x * rc.x, exp2(-9.28 * nv)) * rc.x + rc.y;
        vec2 ab = vec2(-1.04, 1.04) * a004 + rc.zw;
        vec3 reflected = bf_sh_of(bf_spec_sh, r, band);
#ifdef BLENDIFY_PROBE_MAP
        if (bf_probe_inside > 0.5) {  // a metal or solid glass: the scene around it
            reflected = mix(reflected, bf_probe_radiance(bf_probe_parallax(frag_position, r), roughness),
                            max(metallic, bf_glass.x * bf_glass.w));
        }
#endif
        light += reflected * (f0 * ab.x + ab.y);
    }
    return light;
}

