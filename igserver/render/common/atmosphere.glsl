// The one atmosphere function library: sky radiance along a direction and aerial perspective
// for a surface point. Every opaque and water pixel goes through apply_aerial_perspective().
// Needs common/frame.glsl (u_camera_altitude, u_sun_dir, PI) included before it.
//
// Two tiers, chosen per frame by u_sky_model (0 gradient, 1 precomputed) or at compile time by
// SKY_GRADIENT / SKY_PRECOMPUTED (the sky pass):
//
// Gradient tier (seed 003, first approach): with theta the view elevation normalised to [0,1],
//   Coeff = (1 - theta)^2,   colour = zenith + (horizon - zenith) * Coeff,
// zenith/horizon colours (cd/m^2) computed on the CPU from sun elevation and observer altitude,
// plus a halo around the sun whose colour and size follow the sun's elevation; aerial perspective
// is an exponential haze with Koschmieder's extinction.
//
// Precomputed tier (Bruneton & Neyret 2008): the tables of sky/atmosphere_functions.glsl, bound
// on texture units 12..15 by the frame (sky/tables.py). The camera sits at radius
// r = R_g + h above the centre of a spherical earth directly below it (x east, y north, z up):
//   L_sky(v)      = E_sun [ S_R(r, mu, mu_s, nu) P_R(nu) + S_M(...) P_M(nu) ]
//   L(x -> p)     = L_surface T(x, p) + L_sky(v) (1 - T(x, p)) / (1 - T(x, end))   (aerial perspective,
//                   see precomputed_aerial for why not Bruneton's S(x,v) - T(x,p) S(p,v))
#include "sky/atmosphere_functions.glsl"

uniform vec3 u_sky_zenith;      // cd/m^2
uniform vec3 u_sky_horizon;     // cd/m^2
uniform vec3 u_sky_below;       // cd/m^2, below the horizon (ground-reflected haze)
uniform vec3 u_halo_color;      // cd/m^2 at the halo centre
uniform float u_halo_exponent;  // larger = tighter halo
uniform float u_sun_disk_cos;   // cos of the sun's angular radius
uniform vec3 u_sun_disk_luminance; // cd/m^2, after the atmosphere (for reflections)
uniform float u_moon_phase;     // illuminated fraction
uniform vec3 u_fog_color;       // cd/m^2, in-scattered radiance at infinite distance
uniform float u_fog_beta;       // 1/m, extinction at sea level (Koschmieder 3.912 / V)
uniform float u_fog_scale_height; // m

uniform int u_sky_model;           // 0 gradient, 1 precomputed
uniform vec3 u_solar_illuminance;  // lux per channel above the atmosphere
layout(binding = 12) uniform sampler2D u_transmittance_lut;
layout(binding = 13) uniform sampler2D u_irradiance_lut;
layout(binding = 14) uniform sampler3D u_scattering_lut;
layout(binding = 15) uniform sampler3D u_single_mie_lut;

bool use_precomputed() {
#if defined(SKY_PRECOMPUTED)
    return true;
#elif defined(SKY_GRADIENT)
    return false;
#else
    return u_sky_model == 1;
#endif
}

// ---------------------------------------------------------------------------------------------
// Gradient tier
vec3 gradient_sky(vec3 dir) {
    float elevation = asin(clamp(dir.z, -1.0, 1.0));
    float theta = clamp(elevation / (0.5 * PI), 0.0, 1.0);
    float coeff = (1.0 - theta) * (1.0 - theta);
    vec3 sky = u_sky_zenith + (u_sky_horizon - u_sky_zenith) * coeff;
    // Below the horizon: blend to the haze colour over a few degrees so there is no seam.
    sky = mix(sky, u_sky_below, smoothstep(0.0, -0.05, dir.z));
    float c = max(dot(dir, u_sun_dir), 0.0);
    sky += u_halo_color * pow(c, u_halo_exponent) + 0.08 * u_halo_color * c * c * c * c;
    return sky;
}

// (1 - exp(-x)) / x, stable as x -> 0 (series) and for large x.
float one_minus_exp_over_x(float x) {
    return abs(x) < 1e-4 ? 1.0 - 0.5 * x : (1.0 - exp(-x)) / x;
}

// Optical depth of the haze along a segment of length d from the camera, for an exponential
// density exp(-h / H): tau = beta0 * d * exp(-h0/H) * (1 - exp(-dh/H)) / (dh/H).
float haze_optical_depth(vec3 rel) {
    float d = length(rel);
    float h0 = max(u_camera_altitude, 0.0);
    float x = clamp(rel.z / u_fog_scale_height, -80.0, 80.0);
    return u_fog_beta * d * exp(-h0 / u_fog_scale_height) * one_minus_exp_over_x(x);
}

vec3 gradient_aerial_perspective(vec3 radiance, vec3 rel) {
    float transmittance = exp(-min(haze_optical_depth(rel), 80.0));
    return radiance * transmittance + u_fog_color * (1.0 - transmittance);
}

// ---------------------------------------------------------------------------------------------
// Precomputed tier

// Camera radius (km). Altitudes below 1 m are taken as 1 m: float32 radii resolve ~0.5 m, and
// the sky 1 mm above the sea is the sky 1 m above it.
float camera_radius_km() {
    return u_bottom_radius_km + max(u_camera_altitude * 0.001, 0.001);
}

// Moves a camera above the atmosphere to where the ray enters it. Returns false if it never does.
bool enter_atmosphere(inout float r, inout float rmu, out float skipped_km) {
    skipped_km = 0.0;
    if (r <= u_top_radius_km) return true;
    float mu = rmu / r;
    float disc = disc_top(r, mu);
    float d = -rmu - safe_sqrt(disc);
    if (disc < 0.0 || d < 0.0) return false;
    skipped_km = d;
    // New radius is the top; r mu grows by d along the ray.
    rmu += d;
    r = u_top_radius_km;
    return true;
}

// Sky radiance (cd/m^2) along dir, and the transmittance to space (zero when the ray hits the
// ground). Rays below the horizon end on the ground sphere, which is added as a Lambertian
// surface of the ground albedo lit by the sun and the sky, so the lower dome is never black.
vec3 precomputed_sky(vec3 dir, out vec3 transmittance) {
    transmittance = vec3(1.0);
    float r = camera_radius_km();
    float rmu = r * dir.z;
    float skipped;
    if (!enter_atmosphere(r, rmu, skipped)) return vec3(0.0);
    float mu = clamp_cosine(rmu / r);
    // The sun's direction is the same everywhere; mu_s at the entry point follows from geometry.
    vec3 x = vec3(0.0, 0.0, camera_radius_km()) + dir * skipped;
    float mu_s = clamp_cosine(dot(x, u_sun_dir) / r);
    float nu = clamp_cosine(dot(dir, u_sun_dir));
    bool hits_ground = ray_hits_ground(r, mu);
    vec3 s = scattering_lookup(u_scattering_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 m = scattering_lookup(u_single_mie_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 radiance = s * rayleigh_phase(nu) + m * mie_phase(u_mie_g, nu);
    if (hits_ground) {
        float d = distance_to_bottom(r, mu);
        vec3 t = transmittance_segment(u_transmittance_lut, r, mu, d, true);
        vec3 p = x + dir * d;
        vec3 n = normalize(p);
        float mu_s_p = clamp_cosine(dot(n, u_sun_dir));
        vec3 e = transmittance_to_sun(u_transmittance_lut, u_bottom_radius_km, mu_s_p) * max(mu_s_p, 0.0)
               + irradiance_lookup(u_irradiance_lut, u_bottom_radius_km, mu_s_p);
        radiance += t * u_ground_albedo / ATMO_PI * e;
        transmittance = vec3(0.0);
    } else {
        transmittance = exp(-min(optical_depth_to_top(u_transmittance_lut, r, mu), vec3(80.0)));
    }
    return radiance * u_solar_illuminance;
}

// Optical depth of the segment [0, d] from (r, mu): Simpson's rule on the extinction profile
// for segments up to 200 km (the difference of two table lookups is all interpolation error for
// the tens of metres to a surface in haze), the tables beyond.
vec3 segment_optical_depth(float r, float mu, float d, bool hits_ground) {
    if (d > 200.0) return optical_depth_segment(u_transmittance_lut, r, mu, d, hits_ground);
    const int N = 16;  // even
    vec3 sum = vec3(0.0);
    for (int i = 0; i <= N; ++i) {
        float di = d * float(i) / float(N);
        float ri = sqrt(di * di + 2.0 * r * mu * di + r * r);
        float w = (i == 0 || i == N) ? 1.0 : ((i % 2 == 1) ? 4.0 : 2.0);
        sum += w * extinction_km(ri - u_bottom_radius_km);
    }
    return sum * d / (3.0 * float(N));
}

// 1 - exp(-tau), without cancellation for small tau.
vec3 one_minus_exp(vec3 tau) {
    return mix(1.0 - exp(-min(tau, vec3(80.0))), tau * (1.0 - 0.5 * tau), lessThan(tau, vec3(1e-3)));
}

// Transmittance from the camera to a camera-relative point (m) and the in-scattered radiance.
//
// Bruneton's S(x,v) - T(x,p) S(p,v) subtracts two table lookups; with visibility of a few km the
// two are nearly equal for points tens of metres away and the table error (not the physics)
// decides the result. Instead, the in-scattering of the whole ray, S(x,v) (to space or to the
// ground), is shared out along the ray in proportion to its optical depth:
//   I(x -> p) = S(x, v) (1 - T(x,p)) / (1 - T(x,end)),
// exact for a medium of uniform illumination and albedo along the ray, monotone in distance
// and in extinction by construction, and it costs one lookup pair instead of two.
vec3 precomputed_aerial(vec3 radiance, vec3 rel) {
    float d = length(rel) * 0.001;  // km
    if (!(d > 1e-7)) return radiance;
    vec3 dir = rel * (0.001 / d);
    float r = camera_radius_km();
    float rmu = r * dir.z;
    float skipped;
    if (!enter_atmosphere(r, rmu, skipped)) return radiance;
    d -= skipped;
    if (d <= 0.0) return radiance;
    vec3 x = vec3(0.0, 0.0, camera_radius_km()) + dir * skipped;
    float mu = clamp_cosine(rmu / r);
    float mu_s = clamp_cosine(dot(x, u_sun_dir) / r);
    float nu = clamp_cosine(dot(dir, u_sun_dir));
    bool hits_ground = ray_hits_ground(r, mu);
    float d_end = distance_to_nearest_boundary(r, mu, hits_ground);
    // The flat world may put a point past the spherical ground: stop the segment on the ground.
    d = min(d, d_end);
    vec3 tau_p = segment_optical_depth(r, mu, d, hits_ground);
    vec3 tau_end = hits_ground ? optical_depth_segment(u_transmittance_lut, r, mu, d_end, true)
                               : optical_depth_to_top(u_transmittance_lut, r, mu);
    tau_end = max(tau_end, tau_p);
    vec3 share = one_minus_exp(tau_p) / max(one_minus_exp(tau_end), vec3(1e-12));
    share = clamp(share, 0.0, 1.0);
    vec3 s = scattering_lookup(u_scattering_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 m = scattering_lookup(u_single_mie_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 inscatter = (s * rayleigh_phase(nu) + m * mie_phase(u_mie_g, nu)) * u_solar_illuminance * share;
    if (hits_ground) {
        // Below the first altitude row of the table (h_1 = (H / (N_r - 1))^2 / 2 R_g, ~0.5 km)
        // a ground-bound ray's S interpolates between h = 0 (zero path) and h_1 (a long one).
        // Near the ground take the source from the ray just above the horizon instead, whose
        // in-scattering is resolved, and share it out by the optical depth along that ray.
        float n_r = float(textureSize(u_scattering_lut, 0).z);
        float h1 = pow(atmosphere_H() / (n_r - 1.0), 2.0) / (2.0 * u_bottom_radius_km);
        float w = smoothstep(0.0, h1, r - u_bottom_radius_km);
        if (w < 1.0) {
            float mu_h = -safe_sqrt(1.0 - (u_bottom_radius_km / r) * (u_bottom_radius_km / r));
            float mu_up = min(mu_h + 0.002, 1.0);
            vec3 tau_up = optical_depth_to_top(u_transmittance_lut, r, mu_up);
            vec3 s_up = scattering_lookup(u_scattering_lut, r, mu_up, mu_s, nu, false).rgb;
            vec3 m_up = scattering_lookup(u_single_mie_lut, r, mu_up, mu_s, nu, false).rgb;
            vec3 share_up = clamp(one_minus_exp(tau_p) / max(one_minus_exp(max(tau_up, tau_p)), vec3(1e-12)), 0.0, 1.0);
            vec3 near = (s_up * rayleigh_phase(nu) + m_up * mie_phase(u_mie_g, nu)) * u_solar_illuminance * share_up;
            inscatter = mix(near, inscatter, w);
        }
    }
    return radiance * exp(-min(tau_p, vec3(80.0))) + inscatter;
}

// Whether a direction from the camera reaches space rather than the ground.
bool dir_visible(vec3 dir) {
    float r = camera_radius_km();
    return !ray_hits_ground(r, dir.z) && dir.z > -0.5;
}

// Transmittance along a view direction from the camera to space (zero into the ground).
vec3 sky_transmittance(vec3 dir) {
    if (!use_precomputed()) return vec3(1.0);
    vec3 t;
    precomputed_sky(dir, t);
    return t;
}

// ---------------------------------------------------------------------------------------------
// Public API

vec3 sky_radiance(vec3 dir) {
    if (use_precomputed()) {
        vec3 t;
        return precomputed_sky(dir, t);
    }
    return gradient_sky(dir);
}

// Luminance of the sun's disk with limb darkening, zero outside the disk; u_sun_disk_luminance is
// the disk's mean luminance after the atmosphere at the camera.
vec3 sun_disk(vec3 dir) {
    float c = dot(dir, u_sun_dir);
    if (c < u_sun_disk_cos) return vec3(0.0);
    float r = sqrt(max(1.0 - c * c, 0.0)) / sqrt(max(1.0 - u_sun_disk_cos * u_sun_disk_cos, 1e-12));
    float mu = sqrt(max(1.0 - r * r, 0.0));
    // Linear limb darkening I(mu) = I0 (1 - u (1 - mu)), u = 0.6, normalised to mean 1:
    // the disk mean is I0 (1 - u / 3).
    return u_sun_disk_luminance * (1.0 - 0.6 * (1.0 - mu)) / 0.8;
}

// radiance leaving a surface at camera-relative point rel (m), as seen by the camera.
vec3 apply_aerial_perspective(vec3 radiance, vec3 rel) {
    if (use_precomputed()) return precomputed_aerial(radiance, rel);
    return gradient_aerial_perspective(radiance, rel);
}
