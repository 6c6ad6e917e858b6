// Fills the per-frame aerial-perspective table (common/aerial_table.glsl has its layout) from the
// one atmosphere library: a march along each screen node's ray through its slices, with aerial_terms
// (common/atmosphere.glsl) in its two parts: aerial_ray once per ray (the sky-view lookups, the
// fog's phase functions), then aerial_ray_terms at each slice, the clear air's optical depth carried
// from the previous slice (clear_optical_depth_step) instead of a quadrature from the camera.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
// The table's layout, x fastest then y then the slice (the textures are uploaded from these):
// llvmpipe's imageStore into a 3D float image cost ~17 ms of a 20 ms fill, buffer stores ~1.
layout(std430, binding = 0) writeonly buffer OutTau { vec4 u_out_tau[]; };
layout(std430, binding = 1) writeonly buffer OutSource { vec4 u_out_source[]; };
uniform ivec3 u_aerial_size;
uniform int u_aerial_row0;  // the first row of this part of the fill (aerial_table.py: AERIAL_PARTS)
uniform vec4 u_aerial_map;  // d0 (m), log2(q), q, number of slices

void store(ivec3 node, vec3 tau, vec3 inscatter, vec3 scattered) {
    // The mean source S / (1 - T) (1 - T from tau: accurate on the thinnest paths); no optical
    // depth, no source.
    vec3 source = mix(vec3(0.0), inscatter / max(scattered, vec3(1e-30)), greaterThan(scattered, vec3(1e-30)));
    int i = (node.z * u_aerial_size.y + node.y) * u_aerial_size.x + node.x;
    u_out_tau[i] = vec4(tau, 0.0);
    u_out_source[i] = vec4(source, 0.0);
}

void main() {
    // One invocation per screen node, walking its slices (llvmpipe pays a fixed cost per
    // invocation: one per node cost ~6 ms of 27 at 80x45x32).
    ivec2 column = ivec2(gl_GlobalInvocationID.xy) + ivec2(0, u_aerial_row0);
    ivec3 size = u_aerial_size;
    if (any(greaterThanEqual(column, size.xy))) return;
    vec3 dir = view_ray(vec2(column) / vec2(max(size.xy - 1, ivec2(1))));
    if (!use_precomputed()) {
        for (int k = 0; k < size.z; ++k) {
            vec3 tau, inscatter;
            aerial_terms(dir * (u_aerial_map.x * exp2(u_aerial_map.y * float(k))), tau, inscatter);
            store(ivec3(column, k), tau, inscatter, one_minus_exp(tau));
        }
        return;
    }
    AerialRay ray = aerial_ray(dir);
    // Slices within 200 km: the march; past it (the same slices for every node), the per-pixel
    // function's table difference, as clear_segment_optical_depth. Two loops, not a select: a
    // select evaluates both sides in every lane (llvmpipe: the quadrature and the table walk at
    // every slice cost ~2/3 of the fill).
    int near = clamp(int(floor(log2(200e3 / u_aerial_map.x) / u_aerial_map.y)) + 1, 0, size.z);
    vec3 tau_clear = vec3(0.0);
    float prev_km = 0.0;
    for (int k = 0; k < near; ++k) {
        float d = u_aerial_map.x * exp2(u_aerial_map.y * float(k));
        float d_km = 0.001 * d;
        tau_clear += clear_optical_depth_step(ray, prev_km, d_km);
        prev_km = d_km;
        vec3 tau, inscatter, scattered;
        aerial_ray_terms(ray, d, tau_clear, tau, inscatter, scattered);
        store(ivec3(column, k), tau, inscatter, scattered);
    }
    for (int k = near; k < size.z; ++k) {
        float d = u_aerial_map.x * exp2(u_aerial_map.y * float(k));
        vec3 tau, inscatter, scattered;
        aerial_ray_terms(ray, d, clear_segment_optical_depth(dir * d), tau, inscatter, scattered);
        store(ivec3(column, k), tau, inscatter, scattered);
    }
}
