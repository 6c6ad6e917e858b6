// Halos of lights in fog, drawn at reduced resolution (post.py HALO_SCALE) into a small target
// that tonemap.glsl adds with depth-aware upsampling: the halo varies smoothly across the screen
// except where the surface distance jumps, and even one table lookup per end of the ray costs
// several ms per full-resolution frame on llvmpipe.
#include "common/frame.glsl"
#include "common/nearest_distance.glsl"
// Halos of lights in fog (a night fog glows around fires and lamps, more as visibility
// falls): the single-scattered light of each point source along the pixel's view ray up to the
// surface, in a homogeneous medium of the fog's extinction at the camera (beta, albedo omega,
// Henyey-Greenstein g). Closed form through one table (post/halos.py): with h the light's distance
// from the ray, t0 its closest point along it, phi0 = atan(-t0, h), phi1 = atan(D - t0, h),
//   L = omega beta I / h [exp(K(phi0) - beta d) - exp(K(phi1) - beta (D + r1))],
// d the camera-light distance, r1 the surface point-light distance, K(phi, beta h, g) the table.
// The table's phi axis is u = T / (1 + T), T = tan(phi/2 + pi/4) = (s + r) / h at an end of the ray
// (s its signed distance along the ray from t0, r its distance from the light): no inverse tangent,
// and the tail's scaling (halos.py) folds into h_eff: no logarithm but the one of a.
#define MAX_HALOS 8
// HALO_COUNT (1..MAX_HALOS, post.py): the loop below unrolls into exactly that many bodies, where
// a uniform count let the compiler unroll it into MAX_HALOS bodies (its array indexing) run masked.
#ifndef HALO_COUNT
#define HALO_COUNT MAX_HALOS
#endif
uniform vec4 u_halo_pos[MAX_HALOS];        // camera-relative m; w: its length d
uniform vec4 u_halo_intensity[MAX_HALOS];  // cd, linear rgb
uniform float u_halo_beta;                 // 1/m
uniform float u_halo_omega;
uniform sampler2D u_halo_table;            // K(u, log10 a) at the frame's g (post/halos.py), bilinear
uniform vec4 u_halo_table_map;             // (u, log2 h_eff) -> texture coordinates: scale, offset, scale, offset (log10 beta in it)
uniform vec2 u_halo_tail;                  // the table's tail near phi = pi/2: its first u, 1 / its first T (halos.py)

// exp(K(phi, beta h) - beta path) / h at an end of the ray (s, r as above, h floored): T = (s + r) / h
// taken as h / (r - s) where s < 0 (no cancellation), so u = 1 - v or v, v = h / (r + |s| + h). In
// the tail (T over 1 / u_halo_tail.y: the light nearly straight behind this end) K(phi, beta h) =
// K(tail's start, beta h_eff) + log(h / h_eff), h_eff = (s + r) u_halo_tail.y (halos.py); before
// it h_eff = h, and the max below is that.
float halo_end(float s, float r, float h, float path) {
    float v = h / (r + abs(s) + h);
    float u = s >= 0.0 ? 1.0 - v : v;
    float h_eff = max(h, (s + r) * u_halo_tail.y);
    float k = texture(u_halo_table, vec2(min(u, u_halo_tail.x) * u_halo_table_map.x + u_halo_table_map.y,
                                         log2(h_eff) * u_halo_table_map.z + u_halo_table_map.w)).r;
    return exp(k - u_halo_beta * path) / h_eff;
}

// D: the surface distance, at most u_halo_far (past 20 optical depths nothing more is seen).
vec3 light_halos(vec3 dir, float D) {
    vec3 sum = vec3(0.0);
    for (int i = 0; i < HALO_COUNT; ++i) {
        vec3 p = u_halo_pos[i].xyz;
        float d = u_halo_pos[i].w;
        float t0 = dot(p, dir);
        float h = max(length(p - t0 * dir), 0.05);
        float s1 = D - t0;
        float r1 = length(vec2(s1, h));
        // Both ends unconditionally: llvmpipe runs a skipped branch's body anyway.
        float j = halo_end(-t0, d, h, d) - halo_end(s1, r1, h, D + r1);
        sum += u_halo_intensity[i].rgb * (u_halo_omega * u_halo_beta * max(j, 0.0));
    }
    return sum;
}
uniform sampler2D u_distance;  // m along the view ray, full resolution (1e30: sky)
#ifndef HALO_SCALE
#define HALO_SCALE 2  // post.py HALO_SCALE (compiled in)
#endif
uniform float u_halo_far;      // m, 20 / beta
in vec2 v_uv;
out vec4 out_color;

void main() {
    // The nearest surface of the block this pixel covers (as the volumes' reduced march); its
    // distance goes in alpha (log2) for the depth-aware upsampling in tonemap.glsl.
    float d = clamp(nearest_distance(u_distance, ivec2(gl_FragCoord.xy), HALO_SCALE), 1e-3, u_halo_far);
    out_color = vec4(pre_expose(light_halos(view_ray(v_uv), d)), log2(d));
}
