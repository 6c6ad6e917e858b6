#ifndef FOG_RELIEF_GLSL
#define FOG_RELIEF_GLSL
#include "common/noise.glsl"
// Needs the frame uniforms (common/frame.glsl or the sky-view shaders' own): u_sun_dir.

// Relief of a fog top seen from above (sky/frame_sky.py fog_relief_uniforms): the top heaves in
// cells FOG_RELIEF_CELL_M across by ~10 % of the layer's depth (Stull 1988, ch. 11), a height field
// h = A Turb(q) of the project's noise (two octaves) fixed in the world. Sunlight on its slopes
// shades the layer's light by the slope's cosine against the flat top's,
//     f = 1 - (dh/ds) |s_h| / s_z     (s the sun, dh/ds the slope toward it),
// softened to 60 % (multiple scattering inside the top smooths its shading) and clamped to
// 0.6-1.4 for a low sun; the crests, less hidden by their neighbours, a few per cent brighter than
// the troughs. The pattern fades where its cells shrink below ~4 pixels (far, grazing rays: no
// shimmer at the layer's edge). Only the layer's in-scattered light is shaded, from a camera above
// its top (u_fog_relief.z = 0 inside the layer, in haze without a top and for a sun below 2 deg).
uniform vec4 u_fog_relief;  // xy: camera position (noise units, mod period); z: camera height above the top (m), 0: off; w: amplitude (m)
const float FOG_RELIEF_CELL_M = 300.0;
const float FOG_RELIEF_PERIOD = 64.0;  // noise units per axis: the camera offset wraps on it
// FOG_RELIEF 0: a program drawn only while no sunlit fog top lies below the eye (the water pass picks
// the variant per frame) leaves the relief out: llvmpipe runs both sides of the early return below,
// which cost the sea's fragments about 8 % even with the relief off.
#ifndef FOG_RELIEF
#define FOG_RELIEF 1
#endif
#if !FOG_RELIEF
float fog_top_relief(vec3 dir) { return 1.0; }
#else
float fog_top_relief(vec3 dir) {
    if (u_fog_relief.z <= 0.0 || dir.z >= -1e-4) return 1.0;
    float t = u_fog_relief.z / -dir.z;  // m to the top's mean level
    float fade = smoothstep(0.006, 0.02, FOG_RELIEF_CELL_M * -dir.z / t);
    if (fade <= 0.0) return 1.0;
    vec2 q = dir.xy * (t / FOG_RELIEF_CELL_M) + u_fog_relief.xy;
    vec3 period = vec3(FOG_RELIEF_PERIOD, FOG_RELIEF_PERIOD, 0.0);
    float s_h = length(u_sun_dir.xy);
    vec2 toward = u_sun_dir.xy / max(s_h, 1e-6);
    vec4 n = turbulence3_grad(vec3(q, 0.0), period, 2, 23u);  // the height and its gradient at once
    float slope = u_fog_relief.w * dot(n.yz, toward) / FOG_RELIEF_CELL_M;
    float f = clamp(1.0 - 0.6 * slope * s_h / max(u_sun_dir.z, 0.035), 0.6, 1.4) * (1.0 + 0.04 * n.x);
    return mix(1.0, f, fade);
}
#endif
#endif  // FOG_RELIEF_GLSL
