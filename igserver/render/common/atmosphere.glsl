// The one atmosphere function library: sky radiance along a direction and aerial perspective
// for a surface point. Every opaque and water pixel goes through apply_aerial_perspective().
// Needs common/frame.glsl (u_camera_altitude, u_sun_dir, PI) included before it.
//
// Public API (names and meanings stable for every pass):
//   sky_radiance(dir)                 cd/m^2 of the sky (or the far ground) along dir, fog included
//   sky_transmittance(dir)            camera -> space along dir (0 into the ground), fog included
//   sun_disk(dir)                     the sun's limb-darkened disk after the atmosphere and the fog
//   apply_aerial_perspective(L, rel)  radiance leaving a surface at camera-relative rel (m), as seen
//   aerial_terms(rel, tau, S)         the same as optical depth and in-scattering: L exp(-tau) + S
//
// Two tiers, chosen per frame by u_sky_model (0 gradient, 1 precomputed) or at compile time by
// SKY_GRADIENT / SKY_PRECOMPUTED (the sky pass):
//
// Gradient tier (the paper's first approach, docs/design.md#atmosphere): with theta the view elevation normalised to [0,1],
//   Coeff = (1 - theta)^2,   colour = zenith + (horizon - zenith) * Coeff,
// zenith/horizon colours (cd/m^2) computed on the CPU from sun elevation and observer altitude,
// plus a halo around the sun whose colour and size follow the sun's elevation; aerial perspective
// is an exponential haze with Koschmieder's extinction.
//
// Precomputed tier: clear air from the Bruneton & Neyret (2008) tables, fixed per turbidity class,
// evaluated ONCE PER FRAME into the sky-view table (sky/sky_view.glsl: sky radiance, the whole ray's
// in-scattering and its optical depth, per view direction relative to the sun), so a pixel pays one
// or two 2D lookups instead of the 4D walk; plus the near-ground fog/haze layer (sky/haze.py),
// analytic per pixel, so the visibility changes instantly:
//   L(x -> p) = [L_p T_c(x,p) + S_c(x,v) (1 - T_c(x,p)) / (1 - T_c(x,end))] T_h(x,p) + S_h (1 - T_h(x,p))
// (c clear air, h haze). Define ATMOSPHERE_DIRECT_TABLES to evaluate the clear air per pixel from
// the 4D tables instead (the reference of `igserver quality light` for the sky-view table's error).
#include "generated/bindings.glsl"
#include "sky/atmosphere_functions.glsl"
#include "common/fog_relief.glsl"

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
layout(binding = UNIT_TRANSMITTANCE) uniform sampler2D u_transmittance_lut;
layout(binding = UNIT_IRRADIANCE) uniform sampler2D u_irradiance_lut;
layout(binding = UNIT_SCATTERING) uniform sampler3D u_scattering_lut;
layout(binding = UNIT_SINGLE_MIE) uniform sampler3D u_single_mie_lut;

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

// The gradient tier's aerial perspective as optical depth and in-scattering (see aerial_terms).
void gradient_aerial_terms(vec3 rel, out vec3 tau, out vec3 inscatter) {
    float t = haze_optical_depth(rel);
    tau = vec3(t);
    inscatter = u_fog_color * (1.0 - exp(-min(t, 80.0)));
}

// ---------------------------------------------------------------------------------------------
// Precomputed tier: clear air

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
    rmu += d;
    r = u_top_radius_km;
    return true;
}

// 1 - exp(-tau), without cancellation for small tau.
vec3 one_minus_exp(vec3 tau) {
    return mix(1.0 - exp(-min(tau, vec3(80.0))), tau * (1.0 - 0.5 * tau), lessThan(tau, vec3(1e-3)));
}

#if defined(ATMOSPHERE_DIRECT_TABLES) && !defined(ATMOSPHERE_TABLE_WALK)
#define ATMOSPHERE_TABLE_WALK 1
#endif
#ifdef ATMOSPHERE_TABLE_WALK
uniform vec3 u_night_sky;   // cd/m^2 at the zenith: airglow, zodiacal light, faint stars
uniform vec3 u_moon_scale;  // moon / sun illuminance above the atmosphere, per channel (0: no moon)

// Scattered light of one source (sun or moon) along a ray, per unit source illuminance.
// (The per-pixel reference path keeps the plain linear lookup, so it costs what a per-pixel table walk
// always cost; the per-frame sky-view table can afford the geometric one.)
vec3 clear_scattering(float r, float mu, float mu_s, float nu, bool hits_ground) {
#ifdef ATMOSPHERE_DIRECT_TABLES
    vec3 s = scattering_lookup(u_scattering_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 m = scattering_lookup(u_single_mie_lut, r, mu, mu_s, nu, hits_ground).rgb;
#else
    vec3 s = scattering_lookup_geometric(u_scattering_lut, r, mu, mu_s, nu, hits_ground).rgb;
    vec3 m = scattering_lookup_geometric(u_single_mie_lut, r, mu, mu_s, nu, hits_ground).rgb;
#endif
    return s * rayleigh_phase(nu) + m * mie_phase(u_mie_g, nu);
}

// The clear-air view ray from the camera along dir, from the 4D tables (per frame for the
// sky-view table, or per pixel with ATMOSPHERE_DIRECT_TABLES):
//   sky       radiance (cd/m^2) to space, or to the Lambertian ground sphere it hits;
//   inscatter the in-scattered radiance of the whole ray (what aerial perspective shares out);
//   tau_end   the ray's optical depth (1e4 into the ground, so T = 0 there).
void clear_sky_ray(vec3 dir, out vec3 sky, out vec3 inscatter, out vec3 tau_end) {
    sky = vec3(0.0);
    inscatter = vec3(0.0);
    tau_end = vec3(0.0);
    float r = camera_radius_km();
    float rmu = r * dir.z;
    float skipped;
    if (!enter_atmosphere(r, rmu, skipped)) return;
    float mu = clamp_cosine(rmu / r);
    vec3 x = vec3(0.0, 0.0, camera_radius_km()) + dir * skipped;
    float mu_s = clamp_cosine(dot(x, u_sun_dir) / r);
    float nu = clamp_cosine(dot(dir, u_sun_dir));
    bool hits_ground = ray_hits_ground(r, mu);
    vec3 s = clear_scattering(r, mu, mu_s, nu, hits_ground);
    if (u_moon_scale.g > 0.0) {
        float mu_m = clamp_cosine(dot(x, u_moon_dir) / r);
        s += u_moon_scale * clear_scattering(r, mu, mu_m, clamp_cosine(dot(dir, u_moon_dir)), hits_ground);
    }
    inscatter = s * u_solar_illuminance;
    sky = inscatter;
    if (hits_ground) {
        float d = distance_to_bottom(r, mu);
        tau_end = optical_depth_segment(u_transmittance_lut, r, mu, d, true);
        vec3 p = x + dir * d;
        vec3 n = normalize(p);
        float mu_s_p = clamp_cosine(dot(n, u_sun_dir));
        vec3 e = transmittance_to_sun(u_transmittance_lut, u_bottom_radius_km, mu_s_p) * max(mu_s_p, 0.0)
               + irradiance_lookup(u_irradiance_lut, u_bottom_radius_km, mu_s_p);
        sky += exp(-min(tau_end, vec3(80.0))) * u_ground_albedo / ATMO_PI * e * u_solar_illuminance;
        // Near the ground a ground-bound ray's S interpolates between h = 0 (zero path) and the
        // first altitude row h_1 (a long one); take the source from the ray just above the horizon
        // instead (resolved), shared out by optical depth (aerial perspective only).
        float n_r = float(textureSize(u_scattering_lut, 0).z);
        float h1 = pow(atmosphere_H() / (n_r - 1.0), 2.0) / (2.0 * u_bottom_radius_km);
        float w = smoothstep(0.0, h1, r - u_bottom_radius_km);
        if (w < 1.0) {
            float mu_h = -safe_sqrt(1.0 - (u_bottom_radius_km / r) * (u_bottom_radius_km / r));
            float mu_up = min(mu_h + 0.002, 1.0);
            vec3 tau_up = optical_depth_to_top(u_transmittance_lut, r, mu_up);
            vec3 s_up = clear_scattering(r, mu_up, mu_s, nu, false) * u_solar_illuminance;
            vec3 near = s_up * clamp(one_minus_exp(tau_end) / max(one_minus_exp(max(tau_up, tau_end)), vec3(1e-12)), 0.0, 1.0);
            inscatter = mix(near, inscatter, w);
        }
        tau_end = max(tau_end, vec3(1e-6));
        // Marks "hits the ground" for sky_transmittance without a fourth channel.
        tau_end += vec3(1e4);
    } else {
        tau_end = optical_depth_to_top(u_transmittance_lut, r, mu);
        // Natural night sky (airglow, zodiacal light, integrated starlight), van Rhijn brightening
        // toward the horizon (a longer airglow path), attenuated by the air in front of it.
        float up = max(dir.z, 0.0);
        sky += u_night_sky * exp(-min(tau_end, vec3(80.0))) * (1.0 + 2.0 * pow(1.0 - up, 4.0));
    }
}
#endif

// Optical depth (clear air) of the segment from the camera to camera-relative rel (m): 4-point
// Gauss-Legendre on the extinction profile with heights on the sphere, h(s) = h0 + s mu + s^2 (1 -
// mu^2) / 2r (the 4 exponentials of two exponential profiles: smooth, so 4 nodes are exact to
// ~1e-4 over the <= 200 km of a visible surface). Past 200 km, the table difference.
vec3 clear_segment_optical_depth(vec3 rel) {
    float d = length(rel) * 0.001;
    vec3 dir = rel / max(length(rel), 1e-9);
    float r = camera_radius_km();
    float h0 = r - u_bottom_radius_km;
    float mu = dir.z;
    if (d > 200.0 || r > u_top_radius_km) {
        // A camera above the atmosphere: the tables start where the ray enters it (their r is
        // only defined up to the top), and the segment in empty space adds nothing.
        float rmu = r * mu;
        float skipped;
        if (!enter_atmosphere(r, rmu, skipped)) return vec3(0.0);
        mu = clamp_cosine(rmu / r);
        d = max(d - skipped, 0.0);
        bool hits_ground = ray_hits_ground(r, mu);
        d = min(d, distance_to_nearest_boundary(r, mu, hits_ground));
        return optical_depth_segment(u_transmittance_lut, r, mu, d, hits_ground);
    }
    const vec4 X = vec4(-0.8611363116, -0.3399810436, 0.3399810436, 0.8611363116);
    const vec4 W = vec4(0.3478548451, 0.6521451549, 0.6521451549, 0.3478548451);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < 4; ++i) {
        float s = 0.5 * d * (X[i] + 1.0);
        float h = max(h0 + s * mu + s * s * (1.0 - mu * mu) / (2.0 * r), 0.0);
        sum += W[i] * extinction_km(h);
    }
    return sum * 0.5 * d;
}

// ---------------------------------------------------------------------------------------------
// Sky-view table (per frame): see sky/sky_view_map.glsl for the direction <-> texel map.
#include "sky/sky_view_map.glsl"
layout(binding = UNIT_SKY_VIEW_RADIANCE) uniform sampler2D u_sky_view_radiance;   // rgb sky radiance (cd/m^2)
layout(binding = UNIT_SKY_VIEW_INSCATTER) uniform sampler2D u_sky_view_inscatter; // rgb in-scattering of the whole ray
layout(binding = UNIT_SKY_VIEW_TAU) uniform sampler2D u_sky_view_tau;       // rgb optical depth (+1e4 into ground)

void clear_sky_lookup(vec3 dir, out vec3 sky, out vec3 inscatter, out vec3 tau_end, bool need_sky) {
#ifdef ATMOSPHERE_DIRECT_TABLES
    clear_sky_ray(dir, sky, inscatter, tau_end);
#else
    vec2 uv = sky_view_uv_sized(dir, vec2(textureSize(u_sky_view_radiance, 0)));
    sky = need_sky ? texture(u_sky_view_radiance, uv).rgb : vec3(0.0);
    inscatter = need_sky ? vec3(0.0) : texture(u_sky_view_inscatter, uv).rgb;
    tau_end = texture(u_sky_view_tau, uv).rgb;
#endif
}

// ---------------------------------------------------------------------------------------------
// The near-ground fog/haze layer (sky/haze.py has the formulas and their float64 mirror).
uniform vec3 u_haze_beta;        // 1/m, extinction in the dense part (R, G, B)
uniform float u_haze_top;        // m above the ground
uniform float u_haze_edge;       // m, scale height above the top
uniform float u_haze_base;       // m above sea level of the ground
uniform float u_haze_g;          // Henyey-Greenstein asymmetry
uniform float u_haze_omega;      // single-scattering albedo
const float HAZE_EARTH_RADIUS_M = 6360000.0;

bool haze_present() { return u_haze_beta.g > 0.0; }
float haze_height() { return u_camera_altitude - u_haze_base; }
float haze_density(float h) { return h <= u_haze_top ? 1.0 : exp(-min((h - u_haze_top) / u_haze_edge, 80.0)); }
float haze_column(float h) {
    return h <= u_haze_top ? u_haze_top - h + u_haze_edge : u_haze_edge * exp(-min((h - u_haze_top) / u_haze_edge, 80.0));
}
// Optical depth of the straight segment from height h0 over rel (m).
// The same over distance d with height change dz to the end point, given col0 = haze_column(h0).
vec3 haze_segment_tau_from(float h0, float col0, float d, float dz) {
    float mean = abs(dz) < 1e-3 * u_haze_edge ? haze_density(h0 + 0.5 * dz) : (col0 - haze_column(h0 + dz)) / dz;
    return u_haze_beta * (d * max(mean, 0.0));
}
vec3 haze_segment_tau(float h0, vec3 rel) {
    // Height change to the end point above the sphere: rel.z plus the earth's drop there (a sea
    // point at the horizon 357 km from 10 km up is at height 0, not 10 km below sea level).
    float dz = rel.z + dot(rel.xy, rel.xy) / (2.0 * HAZE_EARTH_RADIUS_M);
    return haze_segment_tau_from(h0, haze_column(h0), length(rel), dz);
}
// Optical depth to infinity upward (z > 0, or grazing) on the round earth: the column over the
// path's cosine slant_mu = (z + sqrt(z^2 + 8 H / (pi R))) / 2, H = column / density the local
// scale length: the upper bound of Chapman's grazing function, exact overhead and at the horizon
// (sqrt(pi R / 2H) airmasses, 91 for the 1.2 km haze), the same as HazeLayer.slant_mu that dims the
// sun's light on surfaces and in the fog. (A floor sqrt(z^2 + 2H/R) gave sqrt(R/2H): 1.77x too
// little haze on the horizon, and the sun's disk there up to 8x brighter than the light it casts.)
vec3 haze_tau_up(float h0, float z) {
    float c = haze_column(h0);
    float hc = c / max(haze_density(h0), 1e-6);
    float zp = max(z, 0.0);
    return u_haze_beta * (2.0 * c / (zp + sqrt(zp * zp + 8.0 * hc / (ATMO_PI * HAZE_EARTH_RADIUS_M))));
}
float hg(float g, float nu) {
    // d sqrt(d), not pow(d, 1.5): llvmpipe computes pow as exp2(log2) (~9 % of the sky pass's per-pixel work)
    float d = max(1.0 + g * g - 2.0 * g * nu, 1e-6);
    return (1.0 - g * g) / (4.0 * ATMO_PI * d * sqrt(d));
}
// In-scattered radiance source S(h, dir) of the layer (cd/m^2), from the per-frame table of its
// light against height (sky/haze.py source_table(): the two-stream model evaluated once per frame
// at 64 heights; rows: diffuse down, up, sun beam, moon beam).
layout(binding = UNIT_HAZE_TABLE) uniform sampler2D u_haze_table;
uniform float u_haze_table_top;  // m, height of the table's last column
// The direction's phase functions (sun, moon) come in as phases (haze_phases: once per ray in a march).
vec2 haze_phases(vec3 dir) {
    return vec2(hg(u_haze_g, dot(dir, u_sun_dir)), u_moon_dir.z > 0.0 ? hg(u_haze_g, dot(dir, u_moon_dir)) : 0.0);
}
// The source's parts at height h for a ray of direction z: the sun's and the moon's beams (to be
// weighted by their phases) and the diffuse light (already per steradian), each times omega.
void haze_source_terms(float h, float dir_z, out vec3 sun, out vec3 moon, out vec3 diffuse) {
    float u = tex_coord(clamp(h / u_haze_table_top, 0.0, 1.0), float(textureSize(u_haze_table, 0).x));
    sun = u_haze_omega * texture(u_haze_table, vec2(u, 0.625)).rgb;
    moon = u_moon_dir.z > 0.0 ? u_haze_omega * texture(u_haze_table, vec2(u, 0.875)).rgb : vec3(0.0);
    float w_down = 0.5 + 0.5 * dir_z;  // looking up: light travelling down
    // up (1 - w_down) + down w_down in one bilinear fetch between the two rows' texel centres
    // (0.125: down, 0.375: up; the table is 4 rows, linear-filtered), not two fetches and a mix:
    // the demo's sky pass ~0.97x CPU, frames within 1 level (a GPU's 8-bit filter weights would
    // round w_down to 1/256: |up - down| / 512 at most).
    diffuse = u_haze_omega / ATMO_PI * texture(u_haze_table, vec2(u, 0.375 - 0.25 * w_down)).rgb;
}
// Weight of the lobe for the camera's height: the sky-view table is the clear sky seen from the
// camera, which stands for the sky seen from the layer while the camera is in it: 1 up to the
// layer's top plus one edge, fading to 0 two edges higher (sky/haze_lobe.py lobe_weight mirrors it;
// from higher up the layer is seen from above, its light the two-stream's flux).
float haze_lobe_weight() {
    return 1.0 - smoothstep(u_haze_top + u_haze_edge, u_haze_top + 3.0 * u_haze_edge, haze_height());
}
// The lobe term of direction dir at its ray's source height, times omega and the camera's weight,
// from the per-change table on the sky-view map (sky/haze_lobe.glsl).
layout(binding = UNIT_HAZE_LOBE) uniform sampler2D u_haze_lobe;
vec3 haze_lobe(vec3 dir) {
    if (!haze_present() || haze_lobe_weight() <= 0.0) return vec3(0.0);
    return texture(u_haze_lobe, sky_view_uv_sized(dir, vec2(textureSize(u_haze_lobe, 0)))).rgb;
}
vec3 haze_source_phased(float h, vec3 dir, vec2 phases) {
    vec3 sun, moon, diffuse;
    haze_source_terms(h, dir.z, sun, moon, diffuse);
    return sun * phases.x + moon * phases.y + diffuse;
}
// Height where the ray's in-scattering is gathered: half of the first optical depth's run along it
// (inside the fog: next to the camera; above it: half way down), within [0, d].
float haze_first_depth_run(float h0) { return 1.0 / max(u_haze_beta.g * haze_density(h0), 1e-12); }
float haze_effective_height(float h0, vec3 dir, float d) {
    return h0 + dir.z * 0.5 * min(d, haze_first_depth_run(h0));
}
// The layer along a whole view ray: into the ground (flat, at the layer's base) or to space, as
//   haze_sky(L, dir) = L T + S_diffuse + S_sun p_sun + S_moon p_moon,
// where T and the three S (the source's parts times 1 - T) depend on the ray's height above the
// horizon only and p are the phase functions toward the sun and the moon (haze_phases): the sky pass
// reads all but the moon's term from a table on the sky-view map (sky/sky_hazy.glsl).
struct HazeRay {
    vec3 transmittance;
    vec3 diffuse;
    vec3 sun;   // x the sun's phase
    vec3 moon;  // x the moon's phase
};
// Where a ray from above a fog layer (one with a top) gathers its in-scattering: where its optical depth from the
// camera reaches 1/2 (half the first optical depth, as haze_effective_height inside the layer).
// Down to height h a ray of slope mu (< 0) has crossed the column C(h) (haze_column) at the local
// slope s(h) = sqrt(mu^2 - 2 (h0 - h) / R) (small angles on the sphere), over the round-earth
// cosine (s + sqrt(s^2 + 8 H / (pi R))) / 2 of the edge's scale H (haze_tau_up), so
//     C(h) = 0.5 slant / beta,   h = t + H ln(H / C) above the top t,  t + H - C below it,
// a fixed point reached in three steps from the top; never below the ray's lowest point h_min.
// Looking steeply down it lies a few metres into the fog's top; at its far edge, where rays run
// level for kilometres through the edge's tail, tens of metres above it. (The halfway point of a
// path of 1e7 m put the source at the fog's bottom, lit by twice its top's diffuse light: a bright
// line along the far edge.)
float haze_limb_height(float h0, float mu, float h_min) {
    float top = u_haze_top, edge = u_haze_edge;
    // Haze (no top: one exponential from the ground) and a camera inside the fog: as before.
    if (top <= 0.0 || h0 <= top + edge) return max(h0 + mu * 0.5 * haze_first_depth_run(h0), h_min);
    float floor_term = 8.0 * edge / (ATMO_PI * HAZE_EARTH_RADIUS_M);
    float h = top;
    for (int i = 0; i < 3; ++i) {
        float s = sqrt(max(mu * mu - 2.0 * (h0 - h) / HAZE_EARTH_RADIUS_M, 0.0));
        float c = 0.25 * (s + sqrt(s * s + floor_term)) / max(u_haze_beta.g, 1e-12);
        h = max(c <= edge ? top + edge * log(edge / c) : top + edge - c, h_min);
    }
    return min(h, h0);
}
HazeRay haze_ray(vec3 dir) {
    float h0 = haze_height();
    vec3 tau;
    float d;
    float h_source = -1.0;  // set where the ray's source height is not haze_effective_height's
    if (dir.z < 0.0 && h0 > 0.0) {
        // On the sphere (radius R, camera at r0 = R + h0): a downward ray meets the layer's base
        // only below the dip; above it, it passes a lowest point h_min at s = -r0 mu and climbs out
        // again (the limb), which a flat layer would wrongly close off.
        float r0 = HAZE_EARTH_RADIUS_M + h0;
        float mu = dir.z;
        float disc = r0 * r0 * mu * mu - h0 * (2.0 * HAZE_EARTH_RADIUS_M + h0);
        if (disc >= 0.0) {
            d = -r0 * mu - sqrt(disc);
            tau = haze_segment_tau(h0, dir * d);
        } else {
            float s_t = -r0 * mu;
            float h_min = max(r0 * sqrt(max(1.0 - mu * mu, 0.0)) - HAZE_EARTH_RADIUS_M, 0.0);
            tau = haze_segment_tau(h0, dir * s_t) + haze_tau_up(h_min, 0.0);
            d = 1e30;
            h_source = haze_limb_height(h0, mu, h_min);
        }
    } else if (dir.z < 0.0) {
        d = 1e30;
        tau = vec3(1e4);
    } else {
        tau = haze_tau_up(h0, dir.z);
        d = 1e30;
    }
    HazeRay ray;
    ray.transmittance = exp(-min(tau, vec3(80.0)));
    float hs = h_source >= 0.0 ? h_source : haze_effective_height(h0, dir, min(d, 1e7));
    haze_source_terms(hs, dir.z, ray.sun, ray.moon, ray.diffuse);
    ray.diffuse = max(ray.diffuse + haze_lobe(dir), vec3(0.0));
    vec3 scattered = one_minus_exp(tau);
    ray.sun *= scattered;
    ray.moon *= scattered;
    ray.diffuse *= scattered;
    return ray;
}
vec3 haze_sky(vec3 radiance, vec3 dir, out vec3 transmittance) {
    transmittance = vec3(1.0);
    if (!haze_present()) return radiance;
    HazeRay ray = haze_ray(dir);
    vec2 phases = haze_phases(dir);
    transmittance = ray.transmittance;
    return radiance * ray.transmittance + ray.diffuse + ray.sun * phases.x + ray.moon * phases.y;
}

// ---------------------------------------------------------------------------------------------
// Public API

// Sky radiance (cd/m^2) along dir, and its transmittance to space (zero into the ground).
vec3 sky_radiance_and_transmittance(vec3 dir, out vec3 transmittance) {
    if (!use_precomputed()) {
        transmittance = vec3(dir.z > 0.0 ? 1.0 : 0.0);
        return gradient_sky(dir);
    }
    vec3 sky, inscatter, tau_end;
    clear_sky_lookup(dir, sky, inscatter, tau_end, true);
    vec3 t_clear = tau_end.g >= 1e4 ? vec3(0.0) : exp(-min(tau_end, vec3(80.0)));
    vec3 t_haze;
    vec3 radiance = haze_sky(sky, dir, t_haze);
    transmittance = t_clear * t_haze;
    return radiance;
}

vec3 sky_radiance(vec3 dir) {
    vec3 t;
    return sky_radiance_and_transmittance(dir, t);
}

// The same radiance without the transmittance (one table fetch fewer: the sky pass's per-pixel path).
vec3 sky_radiance_only(vec3 dir) {
#if defined(ATMOSPHERE_DIRECT_TABLES)
    return sky_radiance(dir);
#else
    if (!use_precomputed()) return gradient_sky(dir);
    vec2 uv = sky_view_uv_sized(dir, vec2(textureSize(u_sky_view_radiance, 0)));
    vec3 t_haze;
    return haze_sky(texture(u_sky_view_radiance, uv).rgb, dir, t_haze);
#endif
}

// Transmittance along a view direction from the camera to space (zero into the ground).
vec3 sky_transmittance(vec3 dir) {
    if (!use_precomputed()) return vec3(1.0);
    vec3 sky, inscatter, tau_end;
    clear_sky_lookup(dir, sky, inscatter, tau_end, false);
    if (tau_end.g >= 1e4) return vec3(0.0);
    vec3 t = exp(-min(tau_end, vec3(80.0)));
    if (haze_present()) t *= exp(-min(dir.z > 0.0 ? haze_tau_up(haze_height(), dir.z) : vec3(80.0), vec3(80.0)));
    return t;
}

// Whether a direction from the camera reaches space rather than the ground.
bool dir_visible(vec3 dir) {
    float r = camera_radius_km();
    return !ray_hits_ground(r, dir.z) && dir.z > -0.5;
}

// The sun's disk profile, mean 1 over the disk's solid angle: linear limb darkening I(mu) =
// I0 (1 - u (1 - mu)), u = 0.6 (mean I0 (1 - u/3)). When the disk is smaller than a pixel's
// footprint (u_view_pixel_angle, rad per pixel) its energy is spread over a tent of radius 1.5 px
// instead: a point-sampled disk would flicker on and off between pixel centres as the sun moves.
uniform float u_view_pixel_angle;
float sun_disk_profile(vec3 dir) {
    float radius = acos(clamp(u_sun_disk_cos, -1.0, 1.0));
    float footprint = 1.5 * u_view_pixel_angle;
    float theta = atan(length(cross(dir, u_sun_dir)), dot(dir, u_sun_dir));
    if (footprint > radius) {
        float x = theta / footprint;
        if (x >= 1.0) return 0.0;
        return (radius / footprint) * (radius / footprint) * 3.0 * (1.0 - x);
    }
    float x = theta / radius;
    if (x >= 1.0) return 0.0;
    return (1.0 - 0.6 * (1.0 - sqrt(max(1.0 - x * x, 0.0)))) / 0.8;
}

// Luminance of the sun's disk, zero outside it (limb-darkened, point-sampled: reflections and the
// gradient tier); u_sun_disk_luminance is the disk's mean luminance after the clear air AND the fog
// at the camera. The sky pass draws the disk with sun_disk_profile() (pixel footprint).
vec3 sun_disk(vec3 dir) {
    float c = dot(dir, u_sun_dir);
    if (c < u_sun_disk_cos) return vec3(0.0);
    float r = sqrt(max(1.0 - c * c, 0.0)) / sqrt(max(1.0 - u_sun_disk_cos * u_sun_disk_cos, 1e-12));
    return u_sun_disk_luminance * (1.0 - 0.6 * (1.0 - sqrt(max(1.0 - r * r, 0.0)))) / 0.8;
}

// The air between the camera and camera-relative point rel (m) as its optical depth tau and the
// light it scatters toward the camera: a surface's radiance L is seen as L exp(-tau) + inscatter.
// Clear air first (nearer the camera in the model's composition), then the fog/haze layer.
// In two parts, so that a march along one ray (the aerial table's fill, common/aerial_table.comp.glsl)
// pays what depends on the direction only once: aerial_ray(dir), then aerial_ray_terms at each
// distance d, given the clear air's optical depth to it (clear_segment_optical_depth here; the fill
// accumulates it slice by slice with clear_optical_depth_step). Precomputed atmosphere only.
struct AerialRay {
    vec3 dir;
    vec3 s_clear;        // the clear air's in-scattering of the whole ray (sky-view table)
    vec3 tau_end;        // its optical depth (to the ground or space)
    vec3 end_scattered;  // one_minus_exp(tau_end)
    float r_km, h0_km, curve_km;  // for clear_optical_depth_step: radius, height, (1 - mu^2) / 2r
    float haze_h0, haze_col0, haze_run;  // the layer: camera height, column above it, first depth's run
    vec2 haze_phases;
    vec3 haze_lobe;  // haze_lobe(dir): the layer's phase-weighted sky light at the ray's source height
};
AerialRay aerial_ray(vec3 dir) {
    AerialRay ray;
    ray.dir = dir;
    vec3 sky;
    clear_sky_lookup(dir, sky, ray.s_clear, ray.tau_end, false);
    if (ray.tau_end.g >= 1e4) ray.tau_end -= vec3(1e4);
    ray.end_scattered = max(one_minus_exp(ray.tau_end), vec3(1e-12));
    ray.r_km = camera_radius_km();
    ray.h0_km = ray.r_km - u_bottom_radius_km;
    ray.curve_km = (1.0 - dir.z * dir.z) / (2.0 * ray.r_km);
    ray.haze_h0 = haze_height();
    ray.haze_col0 = haze_column(ray.haze_h0);
    ray.haze_run = haze_first_depth_run(ray.haze_h0);
    ray.haze_phases = haze_phases(dir);
    ray.haze_lobe = haze_lobe(dir);
    return ray;
}
// The clear air's optical depth from distance a to b (km) along the ray: 2-point Gauss-Legendre on
// the extinction profile (a march's slices are short: ratio q ~ 1.4, exact to ~1e-5 of the ray's
// optical depth where the profile varies on the slice's scale). Within 200 km, the camera inside
// the atmosphere (as clear_segment_optical_depth's quadrature).
vec3 clear_optical_depth_step(AerialRay ray, float a, float b) {
    const float X = 0.5773502692;
    float m = 0.5 * (a + b), half_len = 0.5 * (b - a);
    float s0 = m - half_len * X, s1 = m + half_len * X;
    float h0 = max(ray.h0_km + s0 * ray.dir.z + s0 * s0 * ray.curve_km, 0.0);
    float h1 = max(ray.h0_km + s1 * ray.dir.z + s1 * s1 * ray.curve_km, 0.0);
    return (extinction_km(h0) + extinction_km(h1)) * half_len;
}
// The point at distance d (m) on the ray, tau_clear the clear air's optical depth to it: tau and
// inscatter as aerial_terms; scattered = one_minus_exp(tau) (from the two transmittances it has).
void aerial_ray_terms(AerialRay ray, float d, vec3 tau_clear, out vec3 tau, out vec3 inscatter, out vec3 scattered) {
    vec3 tau_p = min(tau_clear, ray.tau_end);
    vec3 t_p = exp(-min(tau_p, vec3(80.0)));
    vec3 share = clamp(mix(1.0 - t_p, tau_p * (1.0 - 0.5 * tau_p), lessThan(tau_p, vec3(1e-3))) / ray.end_scattered,
                       0.0, 1.0);
    vec3 tau_h = vec3(0.0);
    vec3 t_h = vec3(1.0);
    vec3 s_haze = vec3(0.0);
    if (haze_present()) {
        // As haze_aerial_terms: the height change includes the earth's drop (haze_segment_tau).
        float dz = ray.dir.z * d + d * d * (1.0 - ray.dir.z * ray.dir.z) / (2.0 * HAZE_EARTH_RADIUS_M);
        tau_h = haze_segment_tau_from(ray.haze_h0, ray.haze_col0, d, dz);
        t_h = exp(-min(tau_h, vec3(80.0)));
        // From above the layer, a downward ray gathers just under the top it crosses (haze_limb_height).
        float h = u_haze_top > 0.0 && ray.haze_h0 > u_haze_top + u_haze_edge && ray.dir.z < 0.0
                ? haze_limb_height(ray.haze_h0, ray.dir.z, 0.0)
                : ray.haze_h0 + ray.dir.z * 0.5 * min(d, ray.haze_run);
        s_haze = max(haze_source_phased(h, ray.dir, ray.haze_phases) + ray.haze_lobe, vec3(0.0))
               * mix(1.0 - t_h, tau_h * (1.0 - 0.5 * tau_h), lessThan(tau_h, vec3(1e-3)));
    }
    tau = tau_p + tau_h;
    inscatter = ray.s_clear * share * t_h + s_haze;
    scattered = mix(1.0 - t_p * t_h, tau * (1.0 - 0.5 * tau), lessThan(tau, vec3(1e-3)));
}

void aerial_terms(vec3 rel, out vec3 tau, out vec3 inscatter) {
    tau = vec3(0.0);
    inscatter = vec3(0.0);
    if (!use_precomputed()) {
        gradient_aerial_terms(rel, tau, inscatter);
        return;
    }
    float d = length(rel);
    if (!(d > 1e-4)) return;
    vec3 scattered;
    aerial_ray_terms(aerial_ray(rel / d), d, clear_segment_optical_depth(rel), tau, inscatter, scattered);
}

// Radiance leaving a surface at camera-relative point rel (m), as seen by the camera.
vec3 apply_aerial_perspective(vec3 radiance, vec3 rel) {
    vec3 tau, inscatter;
    aerial_terms(rel, tau, inscatter);
    return radiance * exp(-min(tau, vec3(80.0))) + inscatter * fog_top_relief(rel / max(length(rel), 1e-6));
}
