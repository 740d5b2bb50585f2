// Point clouds as exact spheres (fragment side, BLENDIFY_SPHERE): the ray through this pixel's centre
// (gl_FragCoord, perspective or orthographic P) meets the sphere of blendify_sphere_vert.glsl exactly;
// bf_sphere_hit() sets the hit's world position and normal, planar depth and gl_FragDepth.
// bf_sphere_mode: 0 = exact (pixel centres off the sphere are discarded); 3 = solid (pixel centres more than
// half a pixel inside the silhouette, opaque; spheres under 1.5 px are left to the fringe); 2 = fringe (what solid
// leaves: the pixels within half a pixel of the silhouette, and every pixel a sphere under 1.5 px touches, with
// bf_sphere_cover = the covered fraction of the pixel, for blending: unbiased, the area is kept). A sphere under
// 1.5 px is shaded as a whole: at the point facing the eye, its direct light times bf_sphere_direct = 2/3 (the
// mean of n.l over a lit disc is 2/3 of its value at the disc's centre).
// BLENDIFY_POINT_SHADE (with BLENDIFY_SPHERE): every fragment of a target of bf_point_layout.x texels a row shades one
// sphere of a cloud as a whole, for the splat of sub-pixel spheres (render.py, splat_points): fragment g shades
// sphere g x bf_point_layout.y (of bf_point_layout.z) of bf_point_data, seen from the eye, its direct light the mean
// over the visible half (bf_sphere_phase in compute_brdf), shadows looked up at the point facing the eye, the
// world's light with the bands scaled to the disc's mean (blendify_env.glsl); its own colour is applied later.
#ifdef BLENDIFY_SPHERE
uniform mat4 V;
uniform mat4 P;
uniform vec2 bf_viewport;
uniform float bf_sphere_mode;
flat in vec4 bf_sphere;
flat in vec3 bf_sphere_px;
vec3 bf_sphere_pos;
vec3 bf_sphere_normal;
float bf_sphere_depth;
float bf_sphere_cover;
float bf_sphere_direct;
#ifdef BLENDIFY_POINT_SHADE
uniform mat4 M;
uniform sampler2D bf_point_data;  // per sphere (texel = its index, row by row): centre xyz (object units), diameter
uniform ivec3 bf_point_layout;    // the target's width (texels), spheres per fragment, spheres
// screen-space derivatives mean nothing here (neighbouring fragments are unrelated spheres): the soft shadows'
// receiver plane is flat
#define dFdx(x) (0.0 * (x))
#define dFdy(x) (0.0 * (x))

// the mean of max(n.l, 0) over the disc a sphere shows the eye (a Lambertian sphere's phase function), cos_a the
// cosine of the angle between the directions to the eye and to the light: 2/3 facing the light, 0 behind it
float bf_sphere_phase(float cos_a)
{
    float c = clamp(cos_a, -1.0, 1.0);
    float a = acos(c);
    return max((2.0 / 3.0) * (sqrt(1.0 - c * c) + (3.14159265 - a) * c) / 3.14159265, 0.001);
}
#endif

// the view-space point at view depth z on the ray through ndc
vec3 bf_view_at(vec2 ndc, float z)
{
    float w = P[2][3] * z + P[3][3];
    return vec3((ndc.x * w - P[2][0] * z - P[3][0]) / P[0][0], (ndc.y * w - P[2][1] * z - P[3][1]) / P[1][1], z);
}

// the fraction of this pixel a disc of radius rho (pixels) covers: an edge ramp for discs of a pixel or more,
// for smaller ones the overlap of the pixel with the square of the disc's area around its centre
float bf_disc_cover(float dist_px)
{
    float rho = bf_sphere_px.z;
    if (rho >= 0.75) {
        return clamp(rho - dist_px + 0.5, 0.0, 1.0);
    }
    vec2 d = bf_sphere_px.xy - gl_FragCoord.xy;
    float a = 0.5 * 1.7724539 * rho;
    vec2 o = clamp(min(d + a, vec2(0.5)) - max(d - a, vec2(-0.5)), 0.0, 1.0);
    return o.x * o.y;
}

void bf_sphere_hit()
{
#ifdef BLENDIFY_POINT_SHADE
    int index = (int(gl_FragCoord.y) * bf_point_layout.x + int(gl_FragCoord.x)) * bf_point_layout.y;
    index = min(index, bf_point_layout.z - 1);
    int width = textureSize(bf_point_data, 0).x;
    vec4 data = texelFetch(bf_point_data, ivec2(index % width, index / width), 0);
    vec3 centre = (M * vec4(data.xyz, 1.0)).xyz;
    float radius = 0.5 * data.w * length(vec3(M[0]));
    mat3 to_world = transpose(mat3(V));
    vec3 eye = -(to_world * V[3].xyz);
    // toward the eye: along the view axis for an orthographic camera
    vec3 toward = P[2][3] != 0.0 ? normalize(eye - centre) : to_world * vec3(0.0, 0.0, 1.0);
    bf_sphere_normal = toward;
    bf_sphere_pos = centre + radius * toward;
    bf_sphere_depth = dot(to_world * vec3(0.0, 0.0, -1.0), bf_sphere_pos - eye);
    bf_sphere_cover = 1.0;
    bf_sphere_direct = 1.0;
    return;
#endif
    vec2 ndc = 2.0 * gl_FragCoord.xy / bf_viewport - 1.0;
    vec3 o = bf_view_at(ndc, 0.0);
    vec3 d = normalize(bf_view_at(ndc, -1.0) - o);
    vec3 c = bf_sphere.xyz;
    float r = bf_sphere.w;
    float tc = dot(c - o, d);
    vec3 q = o + tc * d - c;  // from the centre to the ray's closest approach
    float q2 = dot(q, q);
    float h2 = r * r - q2;
    float rho = bf_sphere_px.z;
    bool tiny = rho < 0.75;
    bool hit = h2 >= 0.0;
    float dist_px = sqrt(q2) * rho / max(r, 1e-30);  // from the projected centre, in pixels
    bool inner = hit && dist_px <= rho - 0.5;  // more than half a pixel inside the silhouette
    bf_sphere_cover = 1.0;
    bf_sphere_direct = 1.0;
    if (bf_sphere_mode > 2.5) {
        if (tiny || !inner) {
            discard;
        }
    } else if (bf_sphere_mode > 1.5) {
        if (inner && !tiny) {
            discard;  // the solid pass drew it
        }
        bf_sphere_cover = bf_disc_cover(dist_px);
        if (bf_sphere_cover <= 0.0) {
            discard;
        }
    } else if (!hit) {
        discard;
    }
    vec3 nv;
    if (tiny && bf_sphere_mode > 1.5) {
        nv = -d;  // the sphere as a whole
        bf_sphere_direct = 2.0 / 3.0;
    } else if (hit) {
        nv = (q - sqrt(h2) * d) / r;
    } else {
        nv = normalize(q);  // the silhouette point nearest the pixel centre
    }
    vec3 p = c + r * nv;
    vec4 clip = P * vec4(p, 1.0);
    gl_FragDepth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
    bf_sphere_depth = -p.z;
    mat3 rt = transpose(mat3(V));
    bf_sphere_normal = rt * nv;
    bf_sphere_pos = rt * (p - V[3].xyz);
}
#endif
