// Sky pass: fills every pixel no surface covered (drawn at infinity, where the depth is still the cleared one):
// sky radiance (sky-view table + fog), the sun's disk (limb-darkened, reddened and dimmed per pixel
// by the view transmittance),
// the moon with its phase, the natural night sky, and the cirrus layer.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "sky/cirrus.glsl"

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

#if defined(CIRRUS) && !defined(CIRRUS_PER_PIXEL)
layout(binding = UNIT_CIRRUS_TABLE) uniform sampler2D u_cirrus_table;  // cirrus_table.glsl, drawn this frame:
layout(binding = UNIT_CIRRUS_HIDE) uniform sampler2D u_cirrus_hide; // the layer's light and its opacity, both x T
// Composite of the table's layer over the radiance behind it: L (1 - alpha T) + rgb alpha T.
vec3 composite_cirrus_table(vec3 radiance) {
    return radiance * (1.0 - texture(u_cirrus_hide, v_uv).rgb) + texture(u_cirrus_table, v_uv).rgb;
}
#endif
#ifdef SKY_HAZY_TABLE
uniform sampler2D u_sky_hazy;       // the sky through the haze on the sky-view map (sky/sky_hazy.glsl)
uniform sampler2D u_sky_hazy_moon;  // the moon's haze term per row, times its phase per pixel
#endif
uniform float u_moon_disk_cos;       // cos of the moon's angular radius
uniform vec3 u_moon_disk_luminance;  // cd/m^2 of the lit part, after the atmosphere

// The moon's disk with its phase: a point of the disk at offset o (|o| <= 1 in units of the
// angular radius) has the sphere normal n = o - m sqrt(1 - |o|^2) (facing us); it is lit where
// n faces the sun (the sun-moon direction ~ the sun's direction from the earth, 0.15 deg off).
vec3 moon_disk(vec3 dir) {
    float c = dot(dir, u_moon_dir);
    if (c < u_moon_disk_cos) return vec3(0.0);
    float sin_radius = sqrt(max(1.0 - u_moon_disk_cos * u_moon_disk_cos, 1e-12));
    vec3 o = (dir - u_moon_dir * c) / sin_radius;
    vec3 n = o - u_moon_dir * sqrt(max(1.0 - dot(o, o), 0.0));
    return u_moon_disk_luminance * smoothstep(-0.04, 0.04, dot(n, u_sun_dir));
}

// With SURFACE_BELOW (the sea or the ground is ray-cast below the camera), every pixel left to the
// sky lies above that surface's horizon; the atmosphere's own ground sphere (float32 km, altitude
// rounded to ~0.5 m) puts its horizon a fraction of a pixel elsewhere, which showed as a dark
// one-pixel line on the sea horizon at fov <= 1 deg. Such rays are lifted just above the
// atmosphere's horizon (computed with the same float radii as ray_hits_ground).
vec3 above_surface_horizon(vec3 dir) {
#ifdef SURFACE_BELOW
    if (use_precomputed()) {
        float r = camera_radius_km();
        float mu_h = -sqrt(max((r - u_bottom_radius_km) * (r + u_bottom_radius_km), 0.0)) / r;
        float z = 0.98 * mu_h;  // 2 % of the dip above it: clear of float32 rounding in disc_bottom
        if (dir.z < z) {
            vec2 h = dir.xy / max(length(dir.xy), 1e-12);
            dir = vec3(h * sqrt(1.0 - z * z), z);
        }
    }
#endif
    return dir;
}

// The sun's and the moon's disks at one pixel: what the sky pass adds there, through the air and
// the cirrus in front (SKY_DISKS: drawn by sky.py only inside scissor boxes around the two disks;
// on llvmpipe every instruction of a full-screen shader costs on every pixel, and the two disks
// cost 45 % of the sky pass when evaluated everywhere).
vec3 disks(vec3 dir) {
    vec3 t_view = sky_transmittance(dir);
    vec3 radiance;
    if (use_precomputed()) {
        float sun_solid_angle = 2.0 * PI * (1.0 - u_sun_disk_cos);
        radiance = u_solar_illuminance / sun_solid_angle * sun_disk_profile(dir) * t_view;
    } else {
        radiance = sun_disk(dir);
    }
    radiance += moon_disk(dir) * t_view;
#if defined(CIRRUS) && defined(CIRRUS_PER_PIXEL)
    radiance = composite_cirrus(radiance, dir, cirrus_layer(dir)) - composite_cirrus(vec3(0.0), dir, cirrus_layer(dir));
#elif defined(CIRRUS)
    radiance *= 1.0 - texture(u_cirrus_hide, v_uv).rgb;
#endif
    return radiance;
}

// A reddened sun that overexposes: the tone curve (post/tonemap.glsl), per channel, saturates red and
// then green, and showed the setting sun lemon-yellow (255, 245, 98) where the eye sees it orange-red.
// The disk pass marks its pixels for the post pass in the target's alpha (the sky's 1 plus this
// weight; the passes that blend over the sky scale it down by their own coverage): 1 for a disk
// whose green is under 0.3 of its red (the sun within ~2 deg of the horizon in 30 km visibility),
// falling to 0 at 0.5 (~4 deg; the moon and a higher sun are not marked and saturate white as
// before). The HDR radiance itself is untouched.
float disk_hue_weight(vec3 radiance) {
    float m = max(radiance.r, max(radiance.g, radiance.b));
    return m > 0.0 ? 1.0 - smoothstep(0.3, 0.5, radiance.g / m) : 0.0;
}

void main() {
    vec3 dir = above_surface_horizon(view_ray(v_uv));
#ifdef SKY_DISKS
    vec3 disk = disks(dir);
    out_color = vec4(pre_expose(disk), disk_hue_weight(disk));
    out_distance = 0.0;  // added to the sky's 1e30 by the blend
#else
#ifdef SKY_HAZY_TABLE
    vec2 uv = sky_view_uv_sized(dir, vec2(textureSize(u_sky_hazy, 0)));
    vec3 radiance = texture(u_sky_hazy, uv).rgb;
#ifdef SKY_HAZY_MOON
    radiance += texture(u_sky_hazy_moon, vec2(0.5, uv.y)).rgb * haze_phases(dir).y;
#endif
#else
    vec3 radiance = sky_radiance_only(dir);
#endif
#if defined(CIRRUS) && defined(CIRRUS_PER_PIXEL)
    radiance = apply_cirrus(radiance, dir);  // a variant: the noise costs 2x the sky even when skipped
#elif defined(CIRRUS)
    radiance = composite_cirrus_table(radiance);
#endif
    out_color = vec4(pre_expose(radiance), 1.0);
    out_distance = 1e30;  // sky: infinitely far
#endif
}
