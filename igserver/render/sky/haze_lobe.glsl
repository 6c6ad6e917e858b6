// The fog/haze layer's lobe term (common/atmosphere.glsl haze_sky_lobe) of every direction on the
// sky-view map, at the height where that direction's ray gathers its light (aerial_ray's: half the
// first optical depth's run along it), times the single-scattering albedo and the camera's weight:
// the term the sky, the sea and the surfaces add to the layer's source with one lookup
// (haze_lobe), filled once per change of the sky-view table, the layer or the camera's height
// (sky/haze_lobe.py).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;

void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    vec3 dir = sky_view_dir((vec2(texel) + 0.5) / vec2(size));
    float h = max(haze_height() + dir.z * 0.5 * haze_first_depth_run(haze_height()), 0.0);
    imageStore(u_out, texel, vec4(u_haze_omega * haze_lobe_weight() * haze_sky_lobe(h, dir), 0.0));
}
