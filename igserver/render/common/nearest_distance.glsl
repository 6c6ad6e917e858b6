// Reduced-resolution passes (volumes' march, fog halos): the scene distance of a low-resolution
// pixel is the NEAREST of the scale x scale full-resolution pixels it covers, so what is computed
// there for the nearest surface is never drawn over it; the depth-aware upsampling fills the
// further pixels from neighbours whose distance matches theirs. Callers pass scale as a compile-time
// constant (a define): the loops unroll into scale^2 fetches, where a uniform bound cost llvmpipe a
// loop's bookkeeping per pixel; at scale 2 one textureGather takes the four texels (cheaper on
// llvmpipe than four fetches, the same minimum).
float nearest_distance(sampler2D distance, ivec2 low_pixel, int scale) {
    ivec2 size = textureSize(distance, 0);
    if (scale == 2) {
        // One gather of the 2x2 block around its shared corner (an edge-clamped target: past the
        // last row or column it repeats that one, as the clamped fetches below).
        vec4 q = textureGather(distance, vec2(low_pixel * 2 + 1) / vec2(size));
        return min(min(q.x, q.y), min(q.z, q.w));
    }
    ivec2 base = low_pixel * scale;
    float d = 3.0e38;
    for (int y = 0; y < scale; ++y)
        for (int x = 0; x < scale; ++x)
            d = min(d, texelFetch(distance, min(base + ivec2(x, y), size - 1), 0).r);
    return d;
}

// Depth-aware upsampling (the halos in post/tonemap.glsl, the volumes' volumes/upsample.frag.glsl): of
// the four low-resolution texels a textureGather returns — (0,1), (1,1), (1,0), (0,0) relative to the
// lower-left one — the offset of the one whose distance differs least from the pixel's (ties: (0,0),
// then (1,0), (0,1), (1,1)).
vec2 gather_closest_offset(vec4 diff) {
    float best = min(min(diff.x, diff.y), min(diff.z, diff.w));
    return best == diff.w ? vec2(0.0) : best == diff.z ? vec2(1.0, 0.0) : best == diff.x ? vec2(0.0, 1.0) : vec2(1.0);
}
