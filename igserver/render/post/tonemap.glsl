// Post pass: the HDR target is already pre-exposed; tone map (ACES fit, Narkowicz 2015, with the
// highlights' path to white below), encode sRGB, and dither by half an 8-bit step with interleaved
// gradient noise to hide banding. post/exposure.py display_transform mirrors this in numpy for the
// exposure meter: a change here is a change there.
#include "common/frame.glsl"
#include "common/nearest_distance.glsl"

uniform sampler2D u_hdr;

#ifdef HALOS
uniform sampler2D u_halos;    // reduced resolution (post/halos.frag.glsl): rgb pre-exposed halo, a log2 distance
uniform sampler2D u_distance; // m along the view ray (1e30: sky)
uniform float u_halo_far;     // m: distances are clamped to it (20 optical depths)
// Depth-aware upsampling: where the four low-resolution texels around this pixel were computed
// for about its distance (within 23 %: a block's nearest pixel on ground seen at a grazing angle
// is a few rows nearer), the bilinear filter; at a silhouette, the texel of the closest distance,
// so no rim of the far side's halo lies on an object's edge (or the reverse) — read by the same
// bilinear lookup at that texel's centre: one texture access per pixel either way (llvmpipe runs
// both sides of a per-pixel branch).
const float HALO_LOG2_TOLERANCE = 0.3;
vec3 upsampled_halo(vec2 uv) {
    float ld = log2(clamp(texelFetch(u_distance, ivec2(gl_FragCoord.xy), 0).r, 1e-3, u_halo_far));
    vec4 diff = abs(textureGather(u_halos, uv, 3) - ld);  // texels (0,1), (1,1), (1,0), (0,0)
    vec2 size = vec2(textureSize(u_halos, 0));
    vec2 i0 = floor(uv * size - 0.5);
    vec2 nearest = (clamp(i0 + gather_closest_offset(diff), vec2(0.0), size - 1.0) + 0.5) / size;
    return texture(u_halos, all(lessThan(diff, vec4(HALO_LOG2_TOLERANCE))) ? uv : nearest).rgb;
}
#endif
uniform float u_exposure_correction;  // metered exposure / the passes' provisional one (post.py)
uniform float u_rod_fraction;  // mesopic: the rods' share of vision at this frame's adaptation (post.py)

#ifdef MESOPIC
// Mesopic vision: below ~3 cd/m^2 rods take over from cones; at 0.003 cd/m^2 vision is scotopic
// (no colour). Rod fraction from the adaptation luminance (post.py rod_fraction, once per frame),
// rod luminance from linear sRGB with weights near the scotopic curve V'(lambda) (peak 507 nm:
// mostly G and B), shown with a slight blue tint (the "Purkinje" night look, Jensen et al. 2000).
vec3 mesopic(vec3 c) {
    float rod = dot(c, vec3(0.02, 0.55, 0.43));
    return mix(c, rod * vec3(0.80, 0.95, 1.25), u_rod_fraction);
}
#endif
in vec2 v_uv;
out vec4 out_color;

vec3 aces_fit(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// Highlight desaturation ("path to white"). The curve above acts per channel, so a saturated
// colour's brightest channel stops at 1 while the light rises and the others never catch up: an
// over-exposed blackbody (a fire's core, linear sRGB ~ (460, 63, 0), whose blue is ~0) shows pure
// yellow at any brightness, where film, a camera and the eye show yellow-white. Once the brightest
// channel's input m passes WHITE_THRESHOLD, the colour moves toward the white of its own brightest
// displayed value t_max by the excess measured in stops:
//     s = clamp(log2(m / WHITE_THRESHOLD) / WHITE_STOPS, 0, 1),   w = s^2 (3 - 2 s),
//     out = t + w (t_max - t),   t = aces_fit(x) per channel.
// - The energy the brightest channel can no longer show goes into the others: t_max is kept and
//   they rise toward it (toward white at the luminance instead would dim the brightest channel).
// - Below the threshold w = 0 exactly: those pixels are bit-identical to the plain curve.
// - Along a ramp k x of any colour every channel is non-decreasing (t_i, t_max and w all are, and
//   t_max >= t_i) and reaches t_max = 1, white, at 2^WHITE_STOPS times the threshold.
// - The HSV hue is kept: the channels' differences all scale by (1 - w), their ratios do not move.
// - w is C1 at both ends (smoothstep): no kink in a gradient's slope (a Mach band) at the threshold.
// - The excess is taken in stops: the response to light above the shoulder is logarithmic (film's
//   D-log E shoulder, the eye's Weber-Fechner law), so each doubling of the light whitens alike.
// WHITE_THRESHOLD 1 is where the curve reaches 0.80 of its range (sRGB 231); WHITE_STOPS 10 makes
// a flame's core 7-9 stops over yellow-white (blue 230-250 of 255) while its edges 1 stop over
// stay orange (w 0.03) and a fire-lit deck 4 stops over turns pale yellow (w 0.35).
// hue_weight (0..1): a low sun's disk (sky/sky.glsl disk_hue_weight) keeps its hue instead: the
// curve on its largest channel, the others in proportion (a red disk that the per-channel curve
// saturates to yellow stays red-orange, as the eye sees it), and by the same weight no path to white.
const float WHITE_THRESHOLD = 1.0;  // display-linear input of the brightest channel
const float WHITE_STOPS = 10.0;     // stops above the threshold where the colour is white
vec3 display_transform(vec3 x, float hue_weight) {
    vec3 t = aces_fit(x);
    float m = max(max(x.r, x.g), x.b);
    if (hue_weight > 0.0) {
        t = mix(t, aces_fit(vec3(m)) * x / max(m, 1e-12), hue_weight);
    }
    float s = clamp(log2(max(m, 1e-30) / WHITE_THRESHOLD) / WHITE_STOPS, 0.0, 1.0);
    float w = s * s * (3.0 - 2.0 * s) * (1.0 - hue_weight);
    return t + w * (vec3(max(max(t.r, t.g), t.b)) - t);
}

vec3 linear_to_srgb(vec3 c) {
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

float interleaved_gradient_noise(vec2 p) {
    return fract(52.9829189 * fract(dot(p, vec2(0.06711056, 0.00583715))));
}

void main() {
    vec4 hdr_a = texture(u_hdr, v_uv);
    vec3 hdr = hdr_a.rgb;
    float hue_weight = clamp(hdr_a.a - 1.0, 0.0, 1.0);  // a low sun's disk (sky/sky.glsl disk_hue_weight)
#ifdef HALOS
    hdr += upsampled_halo(v_uv);
#endif
    hdr *= u_exposure_correction;
    hdr = max(hdr, vec3(0.0));  // no negative radiance; NaN-free inputs are the passes' duty
#ifdef MESOPIC
    hdr = mesopic(hdr);
#endif
    vec3 srgb = linear_to_srgb(display_transform(hdr, hue_weight));
    srgb += (interleaved_gradient_noise(gl_FragCoord.xy) - 0.5) / 255.0;
    out_color = vec4(clamp(srgb, 0.0, 1.0), 1.0);
}
