// Reduced-resolution march, step 1: the scene distance of each low-resolution pixel = the NEAREST
// of the u_scale x u_scale full-resolution pixels it covers. A volume marched to the nearest
// surface is never drawn over it; the full-resolution pixels further away are filled by the
// depth-aware upsampling from neighbours whose distance matches theirs (upsample.frag.glsl).
uniform sampler2D u_scene_distance;  // m, full resolution, 1e30 = sky
uniform int u_scale;
layout(location = 0) out float out_distance;
void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * u_scale;
    ivec2 size = textureSize(u_scene_distance, 0);
    float d = 3.0e38;
    for (int y = 0; y < u_scale; ++y)
        for (int x = 0; x < u_scale; ++x)
            d = min(d, texelFetch(u_scene_distance, min(base + ivec2(x, y), size - 1), 0).r);
    out_distance = d;
}
