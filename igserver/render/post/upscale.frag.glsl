// Upscale of the LDR frame rendered at a reduced internal resolution to the requested size
// (render/scaling.py). Catmull-Rom (the Mitchell-Netravali cubic with B = 0, C = 0.5) over the 4x4
// source texels around the output pixel: it interpolates (passes through the texels) and its
// negative lobes restore part of the contrast a bilinear filter loses at edges. Its overshoot at a
// hard edge (up to ~7 % of the step: ringing halos) is clamped to the range of the 2x2 texels
// nearest the sample, the edge-aware part: in smooth areas the clamp never binds, at an edge the
// result stays between the two sides. Then an optional unsharp mask against the same 2x2
// neighbourhood's mean (u_sharpen; 0 in production: it trades PSNR for SSIM, see scaling.py),
// clamped the same way.
// The source is sRGB-encoded 8-bit (the post pass's output): the filter works in that perceptual
// space, as display upscalers do, so its error is spread evenly over the grey levels.
uniform sampler2D u_source;   // LDR frame at the internal size, NEAREST filtered (texelFetch only)
uniform vec2 u_scale;         // source size / output size, per axis
uniform float u_sharpen;      // unsharp amount

in vec2 v_uv;
out vec4 f_color;

uniform vec2 u_bc;            // (B, C) of the Mitchell-Netravali cubic: (0, 0.5) = Catmull-Rom

// The Mitchell-Netravali cubic k(x) (1988), |x| < 2, in its (B, C) family.
float bc_cubic(float x) {
    float B = u_bc.x, C = u_bc.y;
    x = abs(x);
    float x2 = x * x, x3 = x2 * x;
    if (x < 1.0)
        return ((12.0 - 9.0 * B - 6.0 * C) * x3 + (-18.0 + 12.0 * B + 6.0 * C) * x2 + (6.0 - 2.0 * B)) / 6.0;
    return ((-B - 6.0 * C) * x3 + (6.0 * B + 30.0 * C) * x2 + (-12.0 * B - 48.0 * C) * x + (8.0 * B + 24.0 * C)) / 6.0;
}

// Weights of the four taps at offsets -1, 0, 1, 2 from the texel left of the sample, t in [0, 1)
// the sample's fraction past that texel. The family sums to 1 for any (B, C); the division only
// removes rounding.
vec4 cubic_weights(float t) {
    vec4 w = vec4(bc_cubic(1.0 + t), bc_cubic(t), bc_cubic(1.0 - t), bc_cubic(2.0 - t));
    return w / dot(w, vec4(1.0));
}

void main() {
    ivec2 size = textureSize(u_source, 0);
    // the output pixel's centre in source texel units (texel centres at i + 0.5)
    vec2 p = gl_FragCoord.xy * u_scale - 0.5;
    vec2 i0 = floor(p);
    vec2 t = p - i0;
#ifdef BILINEAR  // the reference filter the tests compare against
    vec4 wx = vec4(0.0, 1.0 - t.x, t.x, 0.0), wy = vec4(0.0, 1.0 - t.y, t.y, 0.0);
#else
    vec4 wx = cubic_weights(t.x), wy = cubic_weights(t.y);
#endif
    vec4 sum = vec4(0.0);
    vec4 lo = vec4(1.0), hi = vec4(0.0), near_mean = vec4(0.0);
    for (int j = 0; j < 4; ++j) {
        vec4 row = vec4(0.0);
        for (int i = 0; i < 4; ++i) {
            ivec2 q = clamp(ivec2(i0) + ivec2(i - 1, j - 1), ivec2(0), size - 1);
            vec4 c = texelFetch(u_source, q, 0);
            row += wx[i] * c;
            if (i == 1 || i == 2) {
                if (j == 1 || j == 2) {  // the 2x2 texels around the sample
                    lo = min(lo, c);
                    hi = max(hi, c);
                    near_mean += 0.25 * c;
                }
            }
        }
        sum += wy[j] * row;
    }
    vec4 c = clamp(sum, lo, hi);
    c = clamp(c + u_sharpen * (c - near_mean), lo, hi);
    f_color = vec4(c.rgb, 1.0);
}
