// Per-frame sky-view table: the clear-air view ray of every direction (relative to the sun), from
// the 4D tables, once per frame (or when the sun, the moon or the camera's altitude moved). Every
// pass then reads sky radiance, in-scattering and optical depth with one 2D lookup.
#define ATMOSPHERE_TABLE_WALK 1
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = 0, rgba32f) uniform writeonly image2D u_out_radiance;
layout(binding = 1, rgba32f) uniform writeonly image2D u_out_inscatter;
layout(binding = 2, rgba32f) uniform writeonly image2D u_out_tau;

void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out_radiance);
    if (any(greaterThanEqual(texel, size))) return;
    vec3 dir = sky_view_dir((vec2(texel) + 0.5) / vec2(size));
    vec3 sky, inscatter, tau_end;
    clear_sky_ray(dir, sky, inscatter, tau_end);
    imageStore(u_out_radiance, texel, vec4(sky, 0.0));
    imageStore(u_out_inscatter, texel, vec4(inscatter, 0.0));
    imageStore(u_out_tau, texel, vec4(tau_end, 0.0));
}
