// The one atmosphere function library: sky radiance along a direction and aerial perspective
// for a surface point. Every opaque and water pixel goes through apply_aerial_perspective().
//
// Gradient tier (seed 003, first approach): with theta the view elevation normalised to [0,1],
//   Coeff = (1 - theta)^2,   colour = zenith + (horizon - zenith) * Coeff,
// zenith/horizon colours (cd/m^2) computed on the CPU from sun elevation and observer altitude,
// plus a halo around the sun whose colour and size follow the sun's elevation.
uniform vec3 u_sky_zenith;      // cd/m^2
uniform vec3 u_sky_horizon;     // cd/m^2
uniform vec3 u_sky_below;       // cd/m^2, below the horizon (ground-reflected haze)
uniform vec3 u_halo_color;      // cd/m^2 at the halo centre
uniform float u_halo_exponent;  // larger = tighter halo
uniform float u_sun_disk_cos;   // cos of the sun's angular radius
uniform vec3 u_sun_disk_luminance; // cd/m^2
uniform float u_moon_phase;     // illuminated fraction
uniform vec3 u_fog_color;       // cd/m^2, in-scattered radiance at infinite distance
uniform float u_fog_beta;       // 1/m, extinction at sea level (Koschmieder 3.912 / V)
uniform float u_fog_scale_height; // m

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

vec3 sky_radiance(vec3 dir) {
    return gradient_sky(dir);
}

// Luminance of the sun's disk with limb darkening, zero outside the disk.
vec3 sun_disk(vec3 dir) {
    float c = dot(dir, u_sun_dir);
    if (c < u_sun_disk_cos) return vec3(0.0);
    float r = sqrt(max(1.0 - c * c, 0.0)) / sqrt(max(1.0 - u_sun_disk_cos * u_sun_disk_cos, 1e-12));
    float mu = sqrt(max(1.0 - r * r, 0.0));
    return u_sun_disk_luminance * (0.4 + 0.6 * mu);  // linear limb-darkening law, u = 0.6
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
    float x = rel.z / u_fog_scale_height;
    return u_fog_beta * d * exp(-h0 / u_fog_scale_height) * one_minus_exp_over_x(x);
}

// radiance leaving a surface at camera-relative point rel, as seen by the camera.
vec3 apply_aerial_perspective(vec3 radiance, vec3 rel) {
    float transmittance = exp(-min(haze_optical_depth(rel), 80.0));
    return radiance * transmittance + u_fog_color * (1.0 - transmittance);
}
