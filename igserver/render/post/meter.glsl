// Exposure meter: the pre-exposed HDR frame averaged over blocks of u_block x u_block pixels into
// a small RGB image (display-linear, i.e. still multiplied by the frame's provisional exposure),
// read back by post.py to choose the exposure the tone curve applies (per channel, as displayed).
// Each fetch goes through a bilinear sampler (post.py binds one over the target's own nearest
// filtering) at the centre of a 2x2 (or, at a block's odd edge, 2x1, 1x2 or 1x1) group of texels,
// where the filter's weights are exactly equal: the group's mean in one fetch, a quarter of the
// fetches of reading every texel.
#include "generated/bindings.glsl"
layout(local_size_x = 4, local_size_y = 4, local_size_z = 1) in;
layout(binding = UNIT_HDR) uniform sampler2D u_hdr;
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;
uniform int u_block;

void main() {
    ivec2 cell = ivec2(gl_GlobalInvocationID.xy);
    ivec2 out_size = imageSize(u_out);
    if (any(greaterThanEqual(cell, out_size))) return;
    ivec2 size = textureSize(u_hdr, 0);
    vec2 texel = 1.0 / vec2(size);
    ivec2 p0 = cell * u_block;
    ivec2 p1 = min(p0 + ivec2(u_block), size);
    vec3 sum = vec3(0.0);
    for (int y = p0.y; y < p1.y; y += 2) {
        int h = min(2, p1.y - y);
        for (int x = p0.x; x < p1.x; x += 2) {
            int w = min(2, p1.x - x);
            vec2 centre = (vec2(x, y) + 0.5 * vec2(w, h)) * texel;
            sum += max(textureLod(u_hdr, centre, 0.0).rgb, vec3(0.0)) * float(w * h);
        }
    }
    int n = max((p1.x - p0.x) * (p1.y - p0.y), 1);
    imageStore(u_out, cell, vec4(sum / float(n), 1.0));
}
