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
#define MAX_HALOS 8
uniform int u_halo_count;
uniform vec4 u_halo_pos[MAX_HALOS];        // camera-relative m
uniform vec4 u_halo_intensity[MAX_HALOS];  // cd, linear rgb
uniform float u_halo_beta;                 // 1/m
uniform float u_halo_omega;
uniform sampler2D u_halo_table;            // K(phi, log10 a) at the frame's g (post/halos.py), bilinear
uniform vec4 u_halo_table_map;             // (phi, log10 a) -> texture coordinates: scale, offset, scale, offset

uniform vec2 u_halo_tail;                   // the table's tail near phi = pi/2: its first phi, 1 / its width (halos.py)

// In the tail (the light nearly straight behind the ray's start, eps = pi/2 - phi under TAIL)
// K(phi, a) = K(tail's start, a TAIL / eps) + log(eps / TAIL) (halos.py: K ~ log eps + F(a / eps)).
float halo_k(float phi, float log_a) {
    float ratio = clamp((0.5 * PI - phi) * u_halo_tail.y, 1e-30, 1.0);
    float k = texture(u_halo_table, vec2(min(phi, u_halo_tail.x) * u_halo_table_map.x + u_halo_table_map.y,
                                         (log_a - log2(ratio) * 0.30102999566) * u_halo_table_map.z + u_halo_table_map.w)).r;
    return k + log(ratio);
}

// D: the surface distance, at most u_halo_far (past 20 optical depths nothing more is seen).
vec3 light_halos(vec3 dir, float D) {
    vec3 sum = vec3(0.0);
    for (int i = 0; i < MAX_HALOS; ++i) {
        if (i >= u_halo_count) break;
        vec3 p = u_halo_pos[i].xyz;
        float t0 = dot(p, dir);
        float h = max(length(p - t0 * dir), 0.05);
        float phi0 = atan(-t0, h), phi1 = atan(D - t0, h);
        if (phi1 <= phi0) continue;
        float log_a = log2(u_halo_beta * h) * 0.30102999566;  // log10
        float d = length(p);
        float r1 = length(vec2(D - t0, h));
        float j = exp(halo_k(phi0, log_a) - u_halo_beta * d);
        // The far end's term is at most exp(-beta (D + r1)) pi max(p): skip it past 30 optical depths.
        if (u_halo_beta * (D + r1) < 30.0) j -= exp(halo_k(phi1, log_a) - u_halo_beta * (D + r1));
        sum += u_halo_intensity[i].rgb * (u_halo_omega * u_halo_beta / h * max(j, 0.0));
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
