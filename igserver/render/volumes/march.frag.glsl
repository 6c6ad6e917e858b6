// Rendering stage (docs/design.md#fire-and-smoke): march the effect's 3D texture along the view ray.
//
// Ray t in [t0, t1]: t0 = box entry (0 when the camera is inside), t1 = min(box exit, scene
// distance) so ships, the pier and the water clip the effect. The start is shifted by a fraction
// of one step from interleaved-gradient noise (no banding, no white-noise clumping).
// Step length at distance t: step(t) = min(u_step, max(u_voxel, t * u_pixel_angle)), u_step =
// box diagonal / steps. A step longer than a voxel point-samples detail it cannot resolve; where
// a pixel's footprint (t * angle per pixel) is smaller than a voxel, neighbouring rays cross the
// same voxels and differ only by their jitter, so that aliasing became the jitter's own diagonal
// pattern: the stripes seen from inside a plume. Near the camera the step is therefore one voxel;
// further out it grows with the footprint (where neighbouring pixels see different voxels
// anyway) up to the knob's step.
// With BLEND the texture is a blend of two models of the turbulence (re-modelled at a capped
// rate, keyframes at sim times k/rate and (k+1)/rate; modelling.py), weight u_blend of the second.
// Front-to-back, energy conserving per segment of optical depth s = sigma * dt:
//   L += T * S * (1 - exp(-s)),   T *= exp(-s)
// with S the segment's source radiance: fire = emitted colour * luminance (optically thick fire
// tends to S, thin fire adds ~ S * s); smoke = albedo * in-scattered light (single scattering:
// sun and moon through the smoke's own shadow with a Henyey-Greenstein phase, the sky through
// its shadow toward the zenith, and the fire's glow from below). Output is premultiplied:
// (radiance, 1 - T), blended ONE, ONE_MINUS_SRC_ALPHA.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/aerial_table.glsl"

uniform sampler3D u_volume;
#ifdef BLEND
uniform sampler3D u_volume_next;  // weight u_blend (march_block.glsl)
#endif
uniform sampler2D u_scene_distance;  // m along the view ray, 1e30 = sky
uniform float u_pixel_angle;         // rad per pixel of the march's resolution
uniform vec2 u_layer_range;          // cross-fade: drawn where the pixel's dither value is in [x, y) (volumes.py)
// The volume's own constants (box, base, extent, lean, steps, extinction, albedo, emission, glow)
// and the frame's blend and jitter shift.
#include "volumes/march_block.glsl"

in vec3 v_rel;
flat in vec3 v_box_min;  // m, camera-relative AABB of the slab drawn
flat in vec3 v_box_max;
layout(location = 0) out vec4 out_color;

float interleaved_gradient_noise(vec2 p) {
    return fract(52.9829189 * fract(dot(p, vec2(0.06711056, 0.00583715))));
}

float henyey_greenstein(float cos_theta, float g) {
    float d = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (4.0 * PI * d * sqrt(d));
}

// Camera-relative point -> texture coordinates of the bent container.
vec3 to_volume(vec3 p) {
    vec3 q = p - u_base;
    float z = q.z / u_extent.z;
#ifdef SMOKE
    q.xy -= u_lean * (z * z);  // a plume bends over as it loses its buoyant momentum
#else
    q.xy -= u_lean * z;        // a flame tilts as a whole
#endif
    return vec3(q.xy / u_extent.xy * 0.5 + 0.5, z);
}

// Dither value of a pixel for the cross-fade of two march resolutions (a dissolve: each pixel shows
// exactly one of them, so the mix is exact per pixel and linear in the weight over any area).
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
    vec3 dir = normalize(v_rel);
    // Slab test against the AABB.
    vec3 inv = 1.0 / dir;
    vec3 ta = v_box_min * inv, tb = v_box_max * inv;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    float t1 = min(min(tmax.x, tmax.y), tmax.z);
    float scene_t = texelFetch(u_scene_distance, ivec2(gl_FragCoord.xy), 0).r;
    t1 = min(t1, scene_t);
    if (!(t1 > t0)) discard;

    float jitter = fract(interleaved_gradient_noise(gl_FragCoord.xy) + u_jitter_offset);
#ifdef SMOKE
    // Scattering angle between the light's propagation (-l) and the ray back to the eye (-dir).
    // Multiple scattering by octaves (Wrenninge, "Art-Directable Multiple Volumetric Scattering", 2015):
    // order n of the sun's and the moon's light sees the shadow's optical depth x 1/2^n and a phase
    // of asymmetry g / 2^n, weighted (albedo / 2)^n: scattered again with the albedo's chance, and
    // half of that light kept (Wrenninge's b = 1/2; the rest leaves the plume or is counted in the
    // sky term).
    // Single scattering alone draws a dense light smoke seen with the sun behind the eye from its
    // backward lobe (~0.01/sr for g 0.6): wood smoke darker than the sky; black soot (albedo 0.25)
    // barely gains.
    float cos_sun = dot(dir, u_sun_dir), cos_moon = dot(dir, u_moon_dir);
    vec3 direct = u_sun_illuminance * henyey_greenstein(cos_sun, u_hg_g)
                + u_moon_illuminance * henyey_greenstein(cos_moon, u_hg_g);
    vec3 direct1 = u_sun_illuminance * henyey_greenstein(cos_sun, 0.5 * u_hg_g)
                 + u_moon_illuminance * henyey_greenstein(cos_moon, 0.5 * u_hg_g);
    vec3 direct2 = u_sun_illuminance * henyey_greenstein(cos_sun, 0.25 * u_hg_g)
                 + u_moon_illuminance * henyey_greenstein(cos_moon, 0.25 * u_hg_g);
    vec3 sky = u_sky_ambient;  // cd/m^2, isotropic sky light reaching the top of the plume
#endif
    vec3 radiance = vec3(0.0);
    float transmittance = 1.0;
    float depth_weight = 0.0, depth_sum = 0.0;
    // Segments tile [t0, t1] exactly: the first is `jitter` of a step long, each next one step(t)
    // long, the last clipped at t1; each is sampled at its midpoint.
    float sb = t0;
    for (int i = 0; i < 4096 && sb < t1; ++i) {
        float sa = sb;
        float step_here = min(u_step, max(u_voxel, sa * u_pixel_angle));
        sb = min(sa + (i == 0 ? max(jitter, 1e-3) : 1.0) * step_here, t1);
        float tc = 0.5 * (sa + sb);
        vec3 uvw = to_volume(dir * tc);
        if (any(lessThan(uvw, vec3(0.0))) || any(greaterThan(uvw, vec3(1.0)))) continue;
        vec4 voxel = textureLod(u_volume, uvw, 0.0);
#ifdef BLEND
        voxel = mix(voxel, textureLod(u_volume_next, uvw, 0.0), u_blend);
#endif
        float s = voxel.a * u_sigma * (sb - sa);
        if (s <= 1e-6) continue;
        float absorbed = 1.0 - exp(-s);
#ifdef SMOKE
        float albedo = voxel.b * u_albedo_scale;
        float t1 = sqrt(voxel.r), t2 = sqrt(t1);  // the shadow's transmittance at half and a quarter its depth
        float b = 0.5 * albedo;  // each further order: scattered again (the albedo), half of it on (Wrenninge's b)
        vec3 source = albedo * (direct * voxel.r + b * (direct1 * t1 + b * direct2 * t2) + sky * voxel.g);
        vec3 to_glow = u_glow_pos - dir * tc;
        float d2 = max(dot(to_glow, to_glow), 0.25);
        source += albedo * u_glow_intensity / d2 * (0.25 / PI) * voxel.g;  // glow, isotropic, ~shadowed
#else
        vec3 source = voxel.rgb * u_emission;
#endif
        radiance += transmittance * source * absorbed;
        depth_sum += transmittance * absorbed * tc;
        depth_weight += transmittance * absorbed;
        transmittance *= 1.0 - absorbed;
        if (transmittance < 0.004) { transmittance = 0.0; break; }  // opaque: early exit
    }
    float alpha = 1.0 - transmittance;
    if (alpha <= 0.0) discard;
    // Aerial perspective at the opacity-weighted depth, applied to the un-premultiplied colour.
    vec3 rel = dir * (depth_sum / max(depth_weight, 1e-6));
    vec3 colour = aerial_perspective(radiance / alpha, rel) * alpha;  // the frame's table (or AERIAL_EXACT)
    out_color = vec4(pre_expose(colour), alpha);
}
