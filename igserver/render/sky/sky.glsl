// Sky pass: fills every pixel no surface covered (drawn at the far plane with depth test LEQUAL):
// sky radiance, the sun's disk (limb-darkened, reddened per pixel by the view transmittance),
// the moon with its phase, the natural night sky, and the cirrus layer.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "sky/cirrus.glsl"

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

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

void main() {
    vec3 dir = view_ray(v_uv);
    vec3 t_view;  // transmittance from the camera to space along dir (0 into the ground), fog included
    vec3 radiance = sky_radiance_and_transmittance(dir, t_view);
    if (use_precomputed()) {
        float sun_solid_angle = 2.0 * PI * (1.0 - u_sun_disk_cos);
        radiance += u_solar_illuminance / sun_solid_angle * sun_disk_profile(dir) * t_view;
    } else {
        radiance += sun_disk(dir);
    }
    radiance += moon_disk(dir) * t_view;
#ifdef CIRRUS
    radiance = apply_cirrus(radiance, dir);  // a variant: the noise costs 2x the sky even when skipped
#endif
    out_color = vec4(pre_expose(radiance), 1.0);
    out_distance = 1e30;  // sky: infinitely far
}
