// Precomputed atmospheric scattering after Bruneton & Neyret (2008) and Bruneton's 2017
// parameterisation, written for igserver. Shared by the precompute shaders (sky/precompute.glsl)
// and the render-time library (common/atmosphere.glsl).
//
// Geometry: a point at radius r (km) from the earth's centre, a view direction with cosine mu to
// the local zenith, the sun with cosine mu_s to the zenith, and nu = cos(view, sun).
// Tables:
//   transmittance  2D (mu, r):  OPTICAL DEPTH tau(r, mu) to the top of the atmosphere (log-space
//                  transmittance: exp(-tau) underflows float32 in fog, tau does not; T = exp(-tau)).
//   irradiance     2D (mu_s, r): indirect (sky) irradiance on a horizontal plane, per unit solar E.
//   scattering     3D (nu*mu_s, mu, r): Rayleigh single + all multiple orders / RayleighPhase(nu).
//   single_mie     3D, same layout: Mie single scattering without its phase function.
// Radiance is per unit top-of-atmosphere solar irradiance; lengths in km.

uniform float u_bottom_radius_km;
uniform float u_top_radius_km;
uniform vec3 u_rayleigh_scattering_km;   // 1/km at h = 0
uniform float u_rayleigh_scale_height_km;
uniform vec3 u_mie_scattering_km;
uniform vec3 u_mie_extinction_km;
uniform float u_mie_scale_height_km;
uniform float u_mie_g;
uniform vec2 u_mie_background;           // (k_ft, k_st): free-tropospheric, stratospheric aerosol
uniform vec3 u_ozone_absorption_km;      // 1/km at the 25 km peak of the tent profile
uniform float u_ground_albedo;
uniform float u_mu_s_min;                // cos of the largest sun zenith angle in the tables
uniform int u_scattering_nu_size;
uniform int u_scattering_mu_s_size;

const float ATMO_PI = 3.14159265358979;
const float SUN_ANGULAR_RADIUS = 0.004675;  // rad

float clamp_cosine(float mu) { return clamp(mu, -1.0, 1.0); }
float safe_sqrt(float a) { return sqrt(max(a, 0.0)); }
float clamp_radius(float r) { return clamp(r, u_bottom_radius_km, u_top_radius_km); }

// --- ray / shell intersections ------------------------------------------------------------------
// The discriminants are written as (r mu)^2 - (r - R)(r + R) rather than r^2 (mu^2 - 1) + R^2:
// r^2 ~ 4e7 km^2 would leave float32 only ~4 km^2 of resolution at the horizon.
float disc_bottom(float r, float mu) {
    return (r * mu) * (r * mu) - (r - u_bottom_radius_km) * (r + u_bottom_radius_km);
}
float disc_top(float r, float mu) {
    return (r * mu) * (r * mu) - (r - u_top_radius_km) * (r + u_top_radius_km);
}
float distance_to_top(float r, float mu) { return max(-r * mu + safe_sqrt(disc_top(r, mu)), 0.0); }
float distance_to_bottom(float r, float mu) { return max(-r * mu - safe_sqrt(disc_bottom(r, mu)), 0.0); }
bool ray_hits_ground(float r, float mu) { return mu < 0.0 && disc_bottom(r, mu) >= 0.0; }
float distance_to_nearest_boundary(float r, float mu, bool hits_ground) {
    return hits_ground ? distance_to_bottom(r, mu) : distance_to_top(r, mu);
}

// --- composition --------------------------------------------------------------------------------
float rayleigh_density(float h_km) { return exp(-max(h_km, 0.0) / u_rayleigh_scale_height_km); }
// Boundary layer + the background aerosol above it (atmosphere_model.py AtmosphereParameters.mie_density).
float mie_density(float h_km) {
    float h = max(h_km, 0.0);
    return exp(-h / u_mie_scale_height_km) + u_mie_background.x * (exp(-h / 3.0) - exp(-h / 1.2))
         + u_mie_background.y * max(0.0, 1.0 - abs(h - 20.0) / 8.0);
}
float ozone_density(float h_km) { return max(0.0, 1.0 - abs(h_km - 25.0) / 15.0); }
vec3 extinction_km(float h_km) {
    return u_rayleigh_scattering_km * rayleigh_density(h_km) + u_mie_extinction_km * mie_density(h_km)
         + u_ozone_absorption_km * ozone_density(h_km);
}

float rayleigh_phase(float nu) { return 3.0 / (16.0 * ATMO_PI) * (1.0 + nu * nu); }
// Cornette-Shanks; the base is kept >= 1e-6 so that g -> 1 with nu = 1 stays finite.
float mie_phase(float g, float nu) {
    float k = 3.0 / (8.0 * ATMO_PI) * (1.0 - g * g) / (2.0 + g * g);
    return k * (1.0 + nu * nu) / pow(max(1.0 + g * g - 2.0 * g * nu, 1e-6), 1.5);
}

// --- texture coordinates --------------------------------------------------------------------------
// A unit-range value x in [0,1] mapped to texel centres of an n-texel axis and back.
float tex_coord(float x, float n) { return 0.5 / n + x * (1.0 - 1.0 / n); }
float unit_range(float u, float n) { return (u - 0.5 / n) / (1.0 - 1.0 / n); }

float atmosphere_H() {  // distance to the top for a ray tangent to the ground
    return sqrt(u_top_radius_km * u_top_radius_km - u_bottom_radius_km * u_bottom_radius_km);
}
float rho_of(float r) { return safe_sqrt(r * r - u_bottom_radius_km * u_bottom_radius_km); }

// Transmittance table: x_r = rho / H (uniform in the horizon distance), x_mu = (d - d_min) /
// (d_max - d_min) with d the distance to the top (uniform in path length, dense at the horizon).
vec2 transmittance_uv(float r, float mu, vec2 size) {
    float H = atmosphere_H();
    float rho = rho_of(r);
    float d = distance_to_top(r, mu);
    float d_min = u_top_radius_km - r;
    float d_max = rho + H;
    float x_mu = (d - d_min) / max(d_max - d_min, 1e-6);
    return vec2(tex_coord(clamp(x_mu, 0.0, 1.0), size.x), tex_coord(clamp(rho / H, 0.0, 1.0), size.y));
}
void transmittance_r_mu(vec2 uv, vec2 size, out float r, out float mu) {
    float H = atmosphere_H();
    float x_mu = unit_range(uv.x, size.x);
    float x_r = unit_range(uv.y, size.y);
    float rho = H * x_r;
    r = sqrt(rho * rho + u_bottom_radius_km * u_bottom_radius_km);
    float d_min = u_top_radius_km - r;
    float d_max = rho + H;
    float d = d_min + x_mu * (d_max - d_min);
    mu = d == 0.0 ? 1.0 : (H * H - rho * rho - d * d) / (2.0 * r * d);
    mu = clamp_cosine(mu);
}

vec3 optical_depth_to_top(sampler2D lut, float r, float mu) {
    return texture(lut, transmittance_uv(r, mu, vec2(textureSize(lut, 0)))).rgb;
}

// Optical depth along a segment of length d from (r, mu): the difference of two lookups along
// the same line (reversed when the line hits the ground, so both ends see the sky, not the earth).
vec3 optical_depth_segment(sampler2D lut, float r, float mu, float d, bool hits_ground) {
    float r_d = clamp_radius(sqrt(d * d + 2.0 * r * mu * d + r * r));
    float mu_d = clamp_cosine((r * mu + d) / r_d);
    if (hits_ground) {
        return max(optical_depth_to_top(lut, r_d, -mu_d) - optical_depth_to_top(lut, r, -mu), vec3(0.0));
    }
    return max(optical_depth_to_top(lut, r, mu) - optical_depth_to_top(lut, r_d, mu_d), vec3(0.0));
}
vec3 transmittance_segment(sampler2D lut, float r, float mu, float d, bool hits_ground) {
    return exp(-min(optical_depth_segment(lut, r, mu, d, hits_ground), vec3(80.0)));
}

// Transmittance to the sun, times the fraction of its disk above the (geometric) horizon.
vec3 transmittance_to_sun(sampler2D lut, float r, float mu_s) {
    float sin_h = u_bottom_radius_km / r;
    float cos_h = -safe_sqrt(1.0 - sin_h * sin_h);
    float visible = smoothstep(-sin_h * SUN_ANGULAR_RADIUS, sin_h * SUN_ANGULAR_RADIUS, mu_s - cos_h);
    if (visible <= 0.0) return vec3(0.0);
    return exp(-min(optical_depth_to_top(lut, r, mu_s), vec3(80.0))) * visible;
}

// Irradiance table: linear in altitude; uniform in the sun's ELEVATION from asin(mu_s_min) to 90 deg
// (uniform in mu_s put 3.7 deg between columns in twilight, where the irradiance falls by 10x per
// 2 deg, and linear interpolation there made visible steps in the exposure).
float irradiance_x_of_mu_s(float mu_s) {
    float e_min = asin(u_mu_s_min);
    return clamp((asin(clamp(mu_s, -1.0, 1.0)) - e_min) / (0.5 * ATMO_PI - e_min), 0.0, 1.0);
}
float irradiance_mu_s_of_x(float x) {
    float e_min = asin(u_mu_s_min);
    return sin(e_min + x * (0.5 * ATMO_PI - e_min));
}
vec2 irradiance_uv(float r, float mu_s, vec2 size) {
    float x_r = (r - u_bottom_radius_km) / (u_top_radius_km - u_bottom_radius_km);
    return vec2(tex_coord(irradiance_x_of_mu_s(mu_s), size.x), tex_coord(clamp(x_r, 0.0, 1.0), size.y));
}
vec3 irradiance_lookup(sampler2D lut, float r, float mu_s) {
    return texture(lut, irradiance_uv(r, mu_s, vec2(textureSize(lut, 0)))).rgb;
}

// Scattering table (Bruneton 2017): u_r uniform in rho; u_mu split in two halves, rays that hit
// the ground (u_mu < 0.5) and rays that do not, each uniform in the distance to its boundary, so
// that the horizon falls exactly on the seam between the halves; u_mu_s a non-linear map of the
// distance to the top from the ground that puts resolution near the horizon and stops at mu_s_min.
// Sun axis of the scattering table, in the sun's elevation e: the lower half of the rows is
// uniform over twilight, e in [asin(mu_s_min), 0] (1.25 deg per row at 32 rows, where the sky falls
// by 10x per 2-3 deg), the upper half is quadratic from the horizon to the zenith (dense at sunrise,
// sparse at noon where nothing changes). Bruneton's distance-based map left 2-3.5 deg between the
// rows below -9 deg, and the zenith luminance kinked on every row.
const float MU_S_SPLIT = 0.5;
float mu_s_unit(float mu_s) {
    float e = asin(clamp(mu_s, -1.0, 1.0));
    float e_min = asin(u_mu_s_min);
    if (e < 0.0) return MU_S_SPLIT * clamp((e - e_min) / -e_min, 0.0, 1.0);
    return MU_S_SPLIT + (1.0 - MU_S_SPLIT) * sqrt(clamp(e / (0.5 * ATMO_PI), 0.0, 1.0));
}
float mu_s_of_unit(float x) {
    float e_min = asin(u_mu_s_min);
    if (x < MU_S_SPLIT) return sin(e_min * (1.0 - x / MU_S_SPLIT));
    float t = (x - MU_S_SPLIT) / (1.0 - MU_S_SPLIT);
    return sin(0.5 * ATMO_PI * t * t);
}
vec4 scattering_uvwz(float r, float mu, float mu_s, float nu, bool hits_ground, vec3 size) {
    float R_SIZE = size.z, MU_SIZE = size.y, MU_S_SIZE = float(u_scattering_mu_s_size);
    float H = atmosphere_H();
    float rho = rho_of(r);
    float u_r = tex_coord(rho / H, R_SIZE);
    float r_mu = r * mu;
    float u_mu;
    if (hits_ground) {
        float d = -r_mu - safe_sqrt(disc_bottom(r, mu));
        float d_min = r - u_bottom_radius_km;
        float d_max = rho;
        float x = d_max == d_min ? 0.0 : (d - d_min) / (d_max - d_min);
        u_mu = 0.5 - 0.5 * tex_coord(clamp(x, 0.0, 1.0), MU_SIZE / 2.0);
    } else {
        float d = -r_mu + safe_sqrt(disc_bottom(r, mu) + H * H);
        float d_min = u_top_radius_km - r;
        float d_max = rho + H;
        float x = (d - d_min) / max(d_max - d_min, 1e-6);
        u_mu = 0.5 + 0.5 * tex_coord(clamp(x, 0.0, 1.0), MU_SIZE / 2.0);
    }
    float u_mu_s = tex_coord(mu_s_unit(mu_s), MU_S_SIZE);
    float u_nu = (nu + 1.0) / 2.0;
    return vec4(u_nu, u_mu_s, u_mu, u_r);
}

// The 4D table lives in a 3D texture with nu slices side by side along x; interpolate nu by hand.
vec4 scattering_fetch(sampler3D lut, vec4 uvwz) {
    float NU_SIZE = float(u_scattering_nu_size);
    float tex_coord_x = uvwz.x * (NU_SIZE - 1.0);
    float tex_x = floor(tex_coord_x);
    float lerp = tex_coord_x - tex_x;
    vec3 uvw0 = vec3((tex_x + uvwz.y) / NU_SIZE, uvwz.z, uvwz.w);
    vec3 uvw1 = vec3((min(tex_x + 1.0, NU_SIZE - 1.0) + uvwz.y) / NU_SIZE, uvwz.z, uvwz.w);
    return mix(texture(lut, uvw0), texture(lut, uvw1), lerp);
}
vec4 scattering_lookup(sampler3D lut, float r, float mu, float mu_s, float nu, bool hits_ground) {
    vec3 size = vec3(textureSize(lut, 0));
    return scattering_fetch(lut, scattering_uvwz(r, mu, mu_s, nu, hits_ground, size));
}

// The same lookup with GEOMETRIC interpolation between the two nearest sun rows: in twilight the
// scattered light falls exponentially with the sun's depression, and a straight line between rows
// 1.25 deg apart overshoots it by up to 2x and kinks at every row. Costs twice the fetches: used
// once per frame per sky-view texel, not per pixel.
vec4 scattering_lookup_geometric(sampler3D lut, float r, float mu, float mu_s, float nu, bool hits_ground) {
    vec3 size = vec3(textureSize(lut, 0));
    vec4 uvwz = scattering_uvwz(r, mu, mu_s, nu, hits_ground, size);
    float n = float(u_scattering_mu_s_size);
    float f = uvwz.y * n - 0.5;
    float i0 = clamp(floor(f), 0.0, n - 2.0);
    float t = clamp(f - i0, 0.0, 1.0);
    vec4 a = scattering_fetch(lut, vec4(uvwz.x, (i0 + 0.5) / n, uvwz.zw));
    vec4 b = scattering_fetch(lut, vec4(uvwz.x, (i0 + 1.5) / n, uvwz.zw));
    const float TINY = 1e-30;
    return exp(mix(log(max(a, vec4(TINY))), log(max(b, vec4(TINY))), t));
}
