// Fills the per-frame aerial-perspective table (common/aerial_table.glsl has its layout) from the
// one atmosphere library: at each node, aerial_terms (common/atmosphere.glsl), the optical depth
// and in-scattering that apply_aerial_perspective composes.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, rgba32f) uniform writeonly image3D u_out_tau;
layout(binding = 1, rgba32f) uniform writeonly image3D u_out_source;
uniform vec4 u_aerial_map;  // d0 (m), log2(q), q, number of slices

void main() {
    // One invocation per screen node, walking its slices (llvmpipe pays a fixed cost per
    // invocation: one per node cost ~6 ms of 27 at 80x45x32).
    ivec2 column = ivec2(gl_GlobalInvocationID.xy);
    ivec3 size = imageSize(u_out_tau);
    if (any(greaterThanEqual(column, size.xy))) return;
    vec3 dir = view_ray(vec2(column) / vec2(max(size.xy - 1, ivec2(1))));
    for (int k = 0; k < size.z; ++k) {
        vec3 rel = dir * (u_aerial_map.x * exp2(u_aerial_map.y * float(k)));
        vec3 tau, inscatter;
        aerial_terms(rel, tau, inscatter);
        // The mean source S / (1 - T) (1 - T from tau: accurate on the thinnest paths); no optical
        // depth, no source.
        vec3 scattered = one_minus_exp(tau);
        vec3 source = mix(vec3(0.0), inscatter / max(scattered, vec3(1e-30)), greaterThan(scattered, vec3(1e-30)));
        imageStore(u_out_tau, ivec3(column, k), vec4(tau, 0.0));
        imageStore(u_out_source, ivec3(column, k), vec4(source, 0.0));
    }
}
