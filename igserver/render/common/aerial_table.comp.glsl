// Fills the per-frame aerial-perspective table (common/aerial_table.glsl has its layout) from the
// one atmosphere library: at each node, apply_aerial_perspective as the affine map L -> L T + S.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = 0, rgba32f) uniform writeonly image3D u_out_tau;
layout(binding = 1, rgba32f) uniform writeonly image3D u_out_source;
uniform vec4 u_aerial_map;  // d0 (m), log2(q), q, number of slices

void main() {
    ivec3 node = ivec3(gl_GlobalInvocationID);
    ivec3 size = imageSize(u_out_tau);
    if (any(greaterThanEqual(node, size))) return;
    vec3 dir = view_ray(vec2(node.xy) / vec2(max(size.xy - 1, ivec2(1))));
    vec3 rel = dir * (u_aerial_map.x * exp2(u_aerial_map.y * float(node.z)));
    vec3 s = apply_aerial_perspective(vec3(0.0), rel);
    vec3 t = clamp(apply_aerial_perspective(vec3(1.0), rel) - s, vec3(1e-30), vec3(1.0));
    vec3 tau = -log(t);
    // source = S / (1 - T). On a path so thin that 1 - T has few float32 digits left (< 1e-3) the
    // ratio is ill-conditioned: take the source of a longer path along the same ray (the source
    // near the camera changes little over it), up to 1e4 times longer.
    float thin = max(max(1.0 - t.r, 1.0 - t.g), 1.0 - t.b);
    if (thin < 1e-3) {
        rel *= clamp(1e-3 / max(thin, 1e-7), 1.0, 1e4);
        s = apply_aerial_perspective(vec3(0.0), rel);
        t = clamp(apply_aerial_perspective(vec3(1.0), rel) - s, vec3(1e-30), vec3(1.0));
    }
    vec3 source = s / max(vec3(1.0) - t, vec3(6e-8));  // 6e-8: one float32 step below 1
    imageStore(u_out_tau, node, vec4(tau, 0.0));
    imageStore(u_out_source, node, vec4(source, 0.0));
}
