// Cirrus: a thin textured shell at u_cirrus_altitude_km, lit by the sun through the atmosphere and
// shadowed by the earth. Needs common/atmosphere.glsl.
//
// Earth's shadow: from the cloud point p the sun is hidden when the ray p + t s (t > 0) meets the
// earth sphere; 16 rays over a cone of 0.5 deg around the sun (its disk, blurred by refraction)
// give the fraction of the sun still seen, so the shadow's edge sweeps up the layer after sunset
// instead of switching it off. The layer stays lit while the sun is below the observer's horizon:
// at 9 km the sun sets ~3 deg later than on the ground, and later still far away toward the sun.
//
// Light on the layer, the same atmosphere as the sky's (a thin layer, alpha = 1 - exp(-tau)):
//   sun   E_0 T_clear(p -> sun) T_haze(p -> sun) x shadow, phase 0.6 HG(0.75) + 0.4 isotropic; the
//         grazing sun path of a cloud at dusk passes its lowest point inside the near-ground
//         haze/fog layer (sky/haze.py), which the clear-air tables do not hold: without it the
//         layer glowed in full sunlight until the geometric shadow (at EV 12, white on a dark sky);
//   sky   the irradiance table at the cloud's own altitude (less sky above 9 km than at the ground,
//         and in twilight a different sun elevation), half of it seen by a thin layer's phase
//         function: L = E_sky(r_c, mu_s) / 2 pi, plus the ground's reflection (albedo 0.1) from below;
//   path  clear-air AND haze transmittance from the camera to the layer.
#include "common/noise.glsl"

uniform float u_cirrus_coverage;     // 0..1
uniform float u_cirrus_altitude_km;
uniform vec2 u_cirrus_offset;        // noise units, camera position minus wind drift, mod period
uniform float u_cirrus_feature_km;   // noise lattice unit
uniform float u_cirrus_period;       // noise period (units) in x and y

const float CIRRUS_STREAK_X = 0.34375;    // 11/32: streaks stretched ~3:1 along x (with the 3 on y)
const float CIRRUS_SHADOW_CONE = 0.0087;  // rad, half-angle of the softened sun (0.5 deg)

// Fraction of 16 rays around the sun direction from p (km, earth-centred) not blocked by the earth.
float earth_shadow(vec3 p) {
    vec3 s = u_sun_dir;
    vec3 a = normalize(abs(s.z) < 0.9 ? cross(s, vec3(0.0, 0.0, 1.0)) : cross(s, vec3(1.0, 0.0, 0.0)));
    vec3 b = cross(s, a);
    float R = u_bottom_radius_km;
    float lit = 0.0;
    for (int i = 0; i < 16; ++i) {
        // Vogel (golden angle) disk of 16 points: uniform over the cone, no pattern.
        float rr = sqrt((float(i) + 0.5) / 16.0) * CIRRUS_SHADOW_CONE;
        float phi = float(i) * 2.39996323;
        vec3 d = normalize(s + rr * (cos(phi) * a + sin(phi) * b));
        float pd = dot(p, d);
        float disc = pd * pd - (dot(p, p) - R * R);
        bool blocked = pd < 0.0 && disc > 0.0;
        lit += blocked ? 0.0 : 1.0;
    }
    return lit / 16.0;
}

// Henyey-Greenstein, for the forward peak of ice crystals.
float hg_phase(float g, float c) {
    return (1.0 - g * g) / (4.0 * ATMO_PI * pow(max(1.0 + g * g - 2.0 * g * c, 1e-6), 1.5));
}

// Distance (km) from the camera to the layer along dir; -1 where the ray misses it.
float cirrus_distance(vec3 dir) {
    float R = u_bottom_radius_km;
    float r_cam = R + max(u_camera_altitude * 0.001, 0.001);
    float rc = R + u_cirrus_altitude_km;
    // Ray-sphere: |c + t dir| = rc, c = (0, 0, r_cam).
    float b = r_cam * dir.z;
    float disc = b * b - (r_cam - rc) * (r_cam + rc);
    if (disc < 0.0) return -1.0;
    float sq = sqrt(disc);
    float t = r_cam < rc ? -b + sq : -b - sq;  // below: far root (only one ahead); above: near root
    if (t <= 0.0) return -1.0;
    if (r_cam < rc && ray_hits_ground(r_cam, dir.z)) return -1.0;
    return t;
}

// Transmittance from the camera to the layer (clear air and haze); smooth, evaluated per pixel.
vec3 cirrus_transmittance(vec3 dir, float t) {
    if (!use_precomputed()) return vec3(1.0);
    float r_cam = u_bottom_radius_km + max(u_camera_altitude * 0.001, 0.001);
    vec3 t_cam = transmittance_segment(u_transmittance_lut, r_cam, dir.z, t, false);
    if (haze_present()) t_cam *= exp(-min(haze_tau_up(haze_height(), dir.z), vec3(80.0)));
    return t_cam;
}

// The layer along a view direction: (cloud radiance x alpha, alpha), before the camera-to-layer
// transmittance (premultiplied, so a low-resolution table of it interpolates correctly); the
// composite is L (1 - alpha T) + rgb T (apply_cirrus). Zero where the ray misses the layer.
vec4 cirrus_layer(vec3 dir) {
    if (u_cirrus_coverage <= 0.0) return vec4(0.0);
    float R = u_bottom_radius_km;
    float t = cirrus_distance(dir);
    if (t <= 0.0) return vec4(0.0);
    float r_cam = R + max(u_camera_altitude * 0.001, 0.001);
    vec3 p = vec3(0.0, 0.0, r_cam) + dir * t;
    // Layer coordinates: the horizontal offset from the camera (km) in noise units, plus the
    // camera's own (wind-drifted, wrapped) position; streaks stretched 3:1 along x.
    vec2 q = p.xy / u_cirrus_feature_km + u_cirrus_offset;
    vec3 period = vec3(u_cirrus_period, u_cirrus_period, 0.0);
    float n = turbulence3(vec3(q, 0.37), period, 4, 7u);
    // The streak octaves' periods must be whole lattice units (common/noise.glsl) for the layer to
    // wrap on u_cirrus_period without a jump: 64 x 11/32 = 22 (it was 0.35: 22.4, and the streaks
    // jumped each time the drifting offset wrapped, e.g. between the demo's first two frames).
    float streak = turbulence3(vec3(q.x * CIRRUS_STREAK_X, q.y * 3.0, 1.9),
                               vec3(u_cirrus_period * CIRRUS_STREAK_X, u_cirrus_period * 3.0, 0.0), 3, 11u);
    float field = 0.5 + 0.35 * n + 0.25 * streak;
    float threshold = 1.0 - u_cirrus_coverage;
    float density = smoothstep(threshold - 0.1, threshold + 0.3, field);
    // Thin at the horizon where the shell is seen edge-on far away: fade beyond ~150 km.
    density *= exp(-t / 150.0);
    float alpha = clamp(0.7 * density, 0.0, 0.95);
    if (alpha <= 0.0) return vec4(0.0);
    float rp = length(p);
    float mu_s = dot(p, u_sun_dir) / rp;
    float shadow = earth_shadow(p);
    vec3 sun_at_cloud;
    vec3 ambient;
    if (use_precomputed()) {
        float mu_h = -safe_sqrt(1.0 - (R / rp) * (R / rp));
        vec3 tau = optical_depth_to_top(u_transmittance_lut, rp, max(mu_s, mu_h + 1e-4));
        if (haze_present()) {
            // Haze on the sun path: a path that descends (mu_s < 0) passes its lowest point at
            // h_min ahead and crosses the layer there twice (grazing, Chapman floor of haze_tau_up);
            // one that climbs sees the layer above the cloud only.
            float h_cloud = (rp - R) * 1000.0 - u_haze_base;
            float h_min = mu_s < 0.0 ? max(rp * sqrt(max(1.0 - mu_s * mu_s, 0.0)) - R, 0.0) * 1000.0 - u_haze_base
                                     : h_cloud;
            tau += mu_s < 0.0 ? 2.0 * haze_tau_up(max(h_min, 0.0), 0.0) : haze_tau_up(h_cloud, mu_s);
        }
        sun_at_cloud = u_solar_illuminance * exp(-min(tau, vec3(80.0))) * shadow;
        // Sky irradiance at the cloud, scaled from the ground's ambient (which also holds the moon
        // and the night sky) by the table's ratio of the sun's sky light at the two altitudes.
        vec3 e_cloud = irradiance_lookup(u_irradiance_lut, rp, mu_s);
        vec3 e_ground = irradiance_lookup(u_irradiance_lut, R, u_sun_dir.z);
        vec3 ratio = clamp(e_cloud / max(e_ground, vec3(1e-30)), 0.0, 4.0);
        vec3 ground_up = 0.1 * (ATMO_PI * u_sky_ambient + u_sun_illuminance * max(u_sun_dir.z, 0.0));
        ambient = (ATMO_PI * u_sky_ambient * ratio + ground_up) / (2.0 * ATMO_PI);
    } else {
        sun_at_cloud = u_sun_illuminance * shadow;
        ambient = u_sky_ambient * 0.8;
    }
    float c = dot(dir, u_sun_dir);
    float phase = 0.6 * hg_phase(0.75, c) + 0.4 / (4.0 * ATMO_PI);
    vec3 cloud = sun_at_cloud * phase + ambient;
    return vec4(cloud * alpha, alpha);
}

// Composite of a layer sample c = cirrus_layer(dir) (per pixel, or from the per-frame table).
vec3 composite_cirrus(vec3 radiance, vec3 dir, vec4 c) {
    if (c.a <= 0.0) return radiance;
    vec3 t_cam = cirrus_transmittance(dir, max(cirrus_distance(dir), 0.0));
    return radiance * (1.0 - c.a * t_cam) + c.rgb * t_cam;
}
vec3 apply_cirrus(vec3 radiance, vec3 dir) { return composite_cirrus(radiance, dir, cirrus_layer(dir)); }
