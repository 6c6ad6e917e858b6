// Reduced-resolution march, step 3: depth-aware upsampling of the premultiplied volume colour
// (radiance, 1 - transmittance) into the full-resolution frame (blended ONE, ONE_MINUS_SRC_ALPHA).
// Of the four low-resolution pixels around this one, those whose scene distance matches ours
// (relative difference below DEPTH_TOLERANCE) are blended bilinearly; where none matches (an
// edge the low resolution cannot represent), the one with the closest distance is taken, so
// smoke does not bleed across a ship's silhouette and a ship does not cut a hole in the smoke.
// Three texture accesses a pixel (one gather of the four distances, one filtered colour fetch, our
// distance), not nine: llvmpipe pays ~6 ns for each over the whole plume when the camera is in it.
// The filtered fetch's point slides to the matching column or row, which blends exactly the
// matching texels when they are all four, one, or an adjacent pair; two diagonal or three take
// the closest texel instead (edges only: the renormalised blend of those is not a bilinear fetch).
#include "common/nearest_distance.glsl"

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
    float d = min(texelFetch(u_scene_distance, ivec2(gl_FragCoord.xy), 0).r, u_volumes_far);
    vec2 size = vec2(textureSize(u_volume_color, 0));
    vec2 p = gl_FragCoord.xy / float(u_scale) - 0.5;  // in low-resolution texel centres
    vec2 i0 = floor(p);
    vec2 f = p - i0;
    // texels (0,1), (1,1), (1,0), (0,0) around p (edge-clamped like the colour fetch)
    vec4 dq = min(textureGather(u_volume_distance, (i0 + 1.0) / size, 0), vec4(u_volumes_far));
    vec4 diff = abs(dq - d) / max(min(dq, vec4(d)), 1e-3);
    bvec4 match = lessThan(diff, vec4(DEPTH_TOLERANCE));
    // Slide to the column / row that holds every match (f unchanged when both do).
    bool col0 = match.x || match.w, col1 = match.y || match.z;
    bool row0 = match.z || match.w, row1 = match.x || match.y;
    vec2 g = vec2(col1 ? (col0 ? f.x : 1.0) : 0.0, row1 ? (row0 ? f.y : 1.0) : 0.0);
    // weights of (0,1), (1,1), (1,0), (0,0) at g: a non-matching texel with weight left -> closest
    vec4 w = vec4((1.0 - g.x) * g.y, g.x * g.y, g.x * (1.0 - g.y), (1.0 - g.x) * (1.0 - g.y));
    bool clean = any(match) && all(lessThanEqual(w * vec4(not(match)), vec4(0.0)));
    vec2 at = clean ? g : gather_closest_offset(diff);
    out_color = texture(u_volume_color, (clamp(i0 + at, vec2(0.0), size - 1.0) + 0.5) / size);
}
