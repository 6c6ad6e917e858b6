// Evaluates the aerial-perspective table (common/aerial_table.glsl) and the per-pixel function it
// is filled from (common/atmosphere.glsl) at the same points, for tests and error studies:
// point i = u_points[i] (camera-relative m, w: the radiance L leaving the surface, grey, cd/m^2).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/aerial_table.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Points { vec4 u_points[]; };
layout(std430, binding = 1) writeonly buffer Table { vec4 out_table[]; };
layout(std430, binding = 2) writeonly buffer Exact { vec4 out_exact[]; };
uniform int u_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    vec3 rel = u_points[i].xyz;
    vec3 L = vec3(u_points[i].w);
    out_table[i] = vec4(aerial_perspective(L, rel), 0.0);
    out_exact[i] = vec4(apply_aerial_perspective(L, rel), 0.0);
}
