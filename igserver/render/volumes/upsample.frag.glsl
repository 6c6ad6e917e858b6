// Reduced-resolution march, step 3: depth-aware upsampling of the premultiplied volume colour
// (radiance, 1 - transmittance) into the full-resolution frame (blended ONE, ONE_MINUS_SRC_ALPHA).
// Of the four low-resolution pixels around this one, those whose scene distance matches ours
// (relative difference below DEPTH_TOLERANCE) are blended bilinearly; where none matches (an
// edge the low resolution cannot represent), the one with the closest distance is taken, so
// smoke does not bleed across a ship's silhouette and a ship does not cut a hole in the smoke.
uniform sampler2D u_volume_color;     // low resolution, premultiplied
uniform sampler2D u_volume_distance;  // low resolution scene distance used by the march (m)
uniform sampler2D u_scene_distance;   // full resolution (m)
uniform int u_scale;
uniform float u_volumes_far;          // m, farthest point of any volume box: beyond it, every
                                      // distance marches alike (ground 500 m away = the sky)
uniform vec2 u_layer_range;           // cross-fade: drawn where the pixel's dither value is in [x, y) (volumes.py)
layout(location = 0) out vec4 out_color;

// Relative: a low-resolution pixel holds the nearest of its block, so on ground seen at a grazing
// angle it is up to a few rows (~10 %) nearer than this pixel; objects in front of a volume (a
// crate before a fire) differ by far more.
const float DEPTH_TOLERANCE = 0.2;

// The same dither as march.frag.glsl's layer_dither (full-resolution pixels).
float layer_dither(vec2 pixel) {
    return fract(sin(dot(pixel, vec2(12.9898, 78.233))) * 43758.5453);
}

void main() {
#ifdef LAYER_FADE
    // Compiled in only while two march resolutions cross-fade (volumes.py): llvmpipe pays for
    // the hash and the discard on every pixel even when every pixel is kept.
    float keep = layer_dither(floor(gl_FragCoord.xy));
    if (keep < u_layer_range.x || keep >= u_layer_range.y) discard;
#endif
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    float d = min(texelFetch(u_scene_distance, pixel, 0).r, u_volumes_far);
    ivec2 low_size = textureSize(u_volume_color, 0);
    vec2 p = gl_FragCoord.xy / float(u_scale) - 0.5;  // in low-resolution texel centres
    ivec2 i0 = ivec2(floor(p));
    vec2 f = p - vec2(i0);
    vec4 sum = vec4(0.0);
    float weight = 0.0;
    vec4 closest = vec4(0.0);
    float closest_diff = 3.0e38;
    for (int k = 0; k < 4; ++k) {
        ivec2 o = ivec2(k & 1, k >> 1);
        ivec2 q = clamp(i0 + o, ivec2(0), low_size - 1);
        vec4 c = texelFetch(u_volume_color, q, 0);
        float dq = min(texelFetch(u_volume_distance, q, 0).r, u_volumes_far);
        float diff = abs(dq - d) / max(min(dq, d), 1e-3);
        float w = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
        if (diff < DEPTH_TOLERANCE) {
            sum += w * c;
            weight += w;
        }
        if (diff < closest_diff) {
            closest_diff = diff;
            closest = c;
        }
    }
    out_color = weight > 1e-4 ? sum / weight : closest;
}
