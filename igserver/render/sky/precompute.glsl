// Precompute stages of the atmosphere tables (Bruneton & Neyret 2008, successive orders):
//
//   T(x,v)      <- optical depth to the top                            STAGE_TRANSMITTANCE
//   dE(x,s)     <- direct irradiance                                   STAGE_DIRECT_IRRADIANCE
//   dS(x,v,s)   <- single scattering (Rayleigh, Mie separately)        STAGE_SINGLE_SCATTERING
//   for order k = 2..n:
//       dJ      <- scattering density from dS(k-1) and dE(k-2)         STAGE_SCATTERING_DENSITY
//       dE      <- indirect irradiance from dS(k-1);   E += dE         STAGE_INDIRECT_IRRADIANCE
//       dS      <- integral of T(x,y) dJ(y,v,s) dy;  S += dS / P_R(nu) STAGE_MULTIPLE_SCATTERING
//
// One stage per compiled variant; float32 images throughout (half floats lose the deep twilight).
#include "sky/atmosphere_functions.glsl"

#ifdef STAGE_3D
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
#else
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
#endif

layout(binding = 0) uniform sampler2D u_transmittance_in;    // unit 0
layout(binding = 1) uniform sampler2D u_delta_irradiance_in; // unit 1
layout(binding = 2) uniform sampler3D u_delta_rayleigh_in;   // unit 2
layout(binding = 3) uniform sampler3D u_delta_mie_in;        // unit 3
layout(binding = 4) uniform sampler3D u_delta_multiple_in;   // unit 4
layout(binding = 5) uniform sampler3D u_delta_density_in;    // unit 5
uniform int u_order;
uniform int u_z_offset;  // 3D stages run in slabs of altitude rows (short dispatches: progress, liveness)
uniform int u_tail;  // 1 on the last order (>= 3): add the geometric tail of the missing orders

#ifndef DENSITY_SAMPLES
#define DENSITY_SAMPLES 8
#endif

// Texel centre of a 2D table back to unit-range coordinates (inverse of tex_coord per axis).
vec2 unit_range_vec(ivec2 texel, ivec2 size) {
    vec2 uv = (vec2(texel) + 0.5) / vec2(size);
    return vec2(unit_range(uv.x, float(size.x)), unit_range(uv.y, float(size.y)));
}

// (r, mu, mu_s, nu) of a texel of the 3D scattering table.
void scattering_params(ivec3 texel, ivec3 size, out float r, out float mu, out float mu_s, out float nu,
                       out bool hits_ground) {
    float MU_S_SIZE = float(u_scattering_mu_s_size);
    float NU_SIZE = float(u_scattering_nu_size);
    vec3 frag = vec3(texel) + 0.5;
    float frag_nu = floor(frag.x / MU_S_SIZE);
    float frag_mu_s = mod(frag.x, MU_S_SIZE);
    vec4 uvwz = vec4(frag_nu / (NU_SIZE - 1.0), frag_mu_s / MU_S_SIZE, frag.y / float(size.y),
                     frag.z / float(size.z));
    float H = atmosphere_H();
    float rho = H * unit_range(uvwz.w, float(size.z));
    r = sqrt(rho * rho + u_bottom_radius_km * u_bottom_radius_km);
    float MU_HALF = float(size.y) / 2.0;
    if (uvwz.z < 0.5) {
        float d_min = r - u_bottom_radius_km;
        float d_max = rho;
        float d = d_min + (d_max - d_min) * unit_range(1.0 - 2.0 * uvwz.z, MU_HALF);
        mu = d == 0.0 ? -1.0 : clamp_cosine(-(rho * rho + d * d) / (2.0 * r * d));
        hits_ground = true;
    } else {
        float d_min = u_top_radius_km - r;
        float d_max = rho + H;
        float d = d_min + (d_max - d_min) * unit_range(2.0 * uvwz.z - 1.0, MU_HALF);
        mu = d == 0.0 ? 1.0 : clamp_cosine((H * H - rho * rho - d * d) / (2.0 * r * d));
        hits_ground = false;
    }
    mu_s = clamp_cosine(mu_s_of_unit(unit_range(uvwz.y, MU_S_SIZE)));
    nu = clamp_cosine(uvwz.x * 2.0 - 1.0);
    // nu is only free within the range the other two angles allow.
    float s = safe_sqrt((1.0 - mu * mu) * (1.0 - mu_s * mu_s));
    nu = clamp(nu, mu * mu_s - s, mu * mu_s + s);
}

// Radiance of scattering order `order` arriving from direction (mu) at (r, mu_s, nu). `geometric`:
// interpolate GEOMETRICALLY between the sun rows (what the sky-view table shows): in twilight the
// sky falls by ~10x per 2 deg of sun depression, and a straight line between rows 1.25 deg apart
// overshoots; the irradiance integrated from linear lookups came out 24 % above a float64
// hemisphere integral of single scattering at -6 deg (the density stage keeps the linear lookup:
// geometric there doubled its cost for 3 % at -6 deg).
vec4 scattering_lookup_either(sampler3D lut, float r, float mu, float mu_s, float nu, bool hits_ground,
                              bool geometric) {
    return geometric ? scattering_lookup_geometric(lut, r, mu, mu_s, nu, hits_ground)
                     : scattering_lookup(lut, r, mu, mu_s, nu, hits_ground);
}
vec3 scattering_of_order(float r, float mu, float mu_s, float nu, bool hits_ground, int order, bool geometric) {
    if (order == 1) {
        vec3 rayleigh = scattering_lookup_either(u_delta_rayleigh_in, r, mu, mu_s, nu, hits_ground, geometric).rgb;
        vec3 mie = scattering_lookup_either(u_delta_mie_in, r, mu, mu_s, nu, hits_ground, geometric).rgb;
        return rayleigh * rayleigh_phase(nu) + mie * mie_phase(u_mie_g, nu);
    }
    return scattering_lookup_either(u_delta_multiple_in, r, mu, mu_s, nu, hits_ground, geometric).rgb;
}

#if defined(STAGE_TRANSMITTANCE)
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;
void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    float r, mu;
    transmittance_r_mu((vec2(texel) + 0.5) / vec2(size), vec2(size), r, mu);
    // Trapezoid along the ray with samples squeezed toward the start, d_i = D (i/N)^2, where the
    // density is largest for the near-horizontal rays that matter most.
    const int N = 256;
    float D = distance_to_top(r, mu);
    vec3 tau = vec3(0.0);
    float d_prev = 0.0;
    vec3 e_prev = extinction_km(r - u_bottom_radius_km);
    for (int i = 1; i <= N; ++i) {
        float t = float(i) / float(N);
        float d = D * t * t;
        float r_i = sqrt(d * d + 2.0 * r * mu * d + r * r);
        vec3 e = extinction_km(r_i - u_bottom_radius_km);
        tau += 0.5 * (e + e_prev) * (d - d_prev);
        e_prev = e;
        d_prev = d;
    }
    imageStore(u_out, texel, vec4(tau, 0.0));
}

#elif defined(STAGE_DIRECT_IRRADIANCE)
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;
void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    vec2 x = unit_range_vec(texel, size);
    float r = u_bottom_radius_km + x.y * (u_top_radius_km - u_bottom_radius_km);
    float mu_s = irradiance_mu_s_of_x(x.x);
    // Mean cosine over the sun's disk as it crosses the horizon: (mu_s + a)^2 / 4a in between.
    float a = SUN_ANGULAR_RADIUS;
    float cos_factor = mu_s < -a ? 0.0 : (mu_s > a ? mu_s : (mu_s + a) * (mu_s + a) / (4.0 * a));
    vec3 t = exp(-min(optical_depth_to_top(u_transmittance_in, r, mu_s), vec3(80.0)));
    imageStore(u_out, texel, vec4(t * cos_factor, 0.0));
}

#elif defined(STAGE_SINGLE_SCATTERING)
layout(binding = 0, rgba32f) uniform writeonly image3D u_out_rayleigh;
layout(binding = 1, rgba32f) uniform writeonly image3D u_out_mie;
void main() {
    ivec3 texel = ivec3(gl_GlobalInvocationID) + ivec3(0, 0, u_z_offset);
    ivec3 size = imageSize(u_out_rayleigh);
    if (any(greaterThanEqual(texel, size))) return;
    float r, mu, mu_s, nu;
    bool hits_ground;
    scattering_params(texel, size, r, mu, mu_s, nu, hits_ground);
    // J_1 = beta(y) T(x,y) T(y,sun); integrate over the segment to the nearest boundary with the
    // trapezoid rule on d_i = D (i/N)^2: uniform steps over-estimate (convexity) when a 1 km
    // aerosol layer is crossed by 4 km steps; squeezed steps resolve it near the observer.
    const int N = 48;
    float D = distance_to_nearest_boundary(r, mu, hits_ground);
    vec3 rayleigh = vec3(0.0), mie = vec3(0.0);
    float d_prev = 0.0;
    for (int i = 0; i <= N; ++i) {
        float x = float(i) / float(N);
        float d = D * x * x;
        float r_d = clamp_radius(sqrt(d * d + 2.0 * r * mu * d + r * r));
        float mu_s_d = clamp_cosine((r * mu_s + d * nu) / r_d);
        vec3 t = transmittance_segment(u_transmittance_in, r, mu, d, hits_ground)
               * transmittance_to_sun(u_transmittance_in, r_d, mu_s_d);
        // trapezoid weight of node i on a non-uniform grid: (d_{i+1} - d_{i-1}) / 2
        float x_next = float(min(i + 1, N)) / float(N);
        float w = 0.5 * (D * x_next * x_next - d_prev);
        rayleigh += w * t * rayleigh_density(r_d - u_bottom_radius_km);
        mie += w * t * mie_density(r_d - u_bottom_radius_km);
        d_prev = d;
    }
    imageStore(u_out_rayleigh, texel, vec4(rayleigh * u_rayleigh_scattering_km, 0.0));
    imageStore(u_out_mie, texel, vec4(mie * u_mie_scattering_km, 0.0));
}

#elif defined(STAGE_SCATTERING_DENSITY)
layout(binding = 0, rgba32f) uniform writeonly image3D u_out;
void main() {
    ivec3 texel = ivec3(gl_GlobalInvocationID) + ivec3(0, 0, u_z_offset);
    ivec3 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    float r, mu, mu_s, nu;
    bool hits_ground_unused;
    scattering_params(texel, size, r, mu, mu_s, nu, hits_ground_unused);
    // Local frame: zenith z, view omega in the xz plane, sun omega_s from (mu_s, nu).
    vec3 omega = vec3(safe_sqrt(1.0 - mu * mu), 0.0, mu);
    float sx = omega.x == 0.0 ? 0.0 : (nu - mu * mu_s) / omega.x;
    vec3 omega_s = vec3(sx, safe_sqrt(1.0 - sx * sx - mu_s * mu_s), mu_s);
    // In deep twilight the zenith is lit (second order) by the sunlit air low over the horizon
    // toward the sun: 8 zenith-angle steps (22.5 deg) left the zenith 3-5x too dark at -10..-14 deg,
    // 16 (11.25 deg) land within 15 % of Patat et al. 2006 (`igserver quality light`); a
    // horizon-packed map of 8 steps overshot by 2.5x, so the medium preset pays for 16.
    const int NT = DENSITY_SAMPLES;
    float dtheta = ATMO_PI / float(NT);
    float dphi = ATMO_PI / float(NT);
    float h = r - u_bottom_radius_km;
    vec3 beta_r = u_rayleigh_scattering_km * rayleigh_density(h);
    vec3 beta_m = u_mie_scattering_km * mie_density(h);
    vec3 result = vec3(0.0);
    for (int l = 0; l < NT; ++l) {
        float theta = (float(l) + 0.5) * dtheta;
        float ct = cos(theta), st = sin(theta);
        bool ground = ray_hits_ground(r, ct);
        float d_ground = 0.0;
        vec3 t_ground = vec3(0.0);
        if (ground) {
            d_ground = distance_to_bottom(r, ct);
            t_ground = transmittance_segment(u_transmittance_in, r, ct, d_ground, true);
        }
        for (int m = 0; m < 2 * NT; ++m) {
            float phi = (float(m) + 0.5) * dphi;
            vec3 omega_i = vec3(cos(phi) * st, sin(phi) * st, ct);
            float domega = dtheta * dphi * st;
            float nu1 = dot(omega_s, omega_i);
            vec3 incident = scattering_of_order(r, ct, mu_s, nu1, ground, u_order - 1, false);
            if (ground) {
                // Light reflected by the Lambertian ground at the end of omega_i.
                vec3 n = normalize(vec3(0.0, 0.0, r) + omega_i * d_ground);
                vec3 e = irradiance_lookup(u_delta_irradiance_in, u_bottom_radius_km, dot(n, omega_s));
                incident += t_ground * u_ground_albedo / ATMO_PI * e;
            }
            float nu2 = dot(omega, omega_i);
            result += incident * (beta_r * rayleigh_phase(nu2) + beta_m * mie_phase(u_mie_g, nu2)) * domega;
        }
    }
    imageStore(u_out, texel, vec4(result, 0.0));
}

#elif defined(STAGE_INDIRECT_IRRADIANCE)
layout(binding = 0, rgba32f) uniform writeonly image2D u_out_delta;
layout(binding = 1, rgba32f) uniform image2D u_accumulate;
void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out_delta);
    if (any(greaterThanEqual(texel, size))) return;
    vec2 x = unit_range_vec(texel, size);
    float r = u_bottom_radius_km + x.y * (u_top_radius_km - u_bottom_radius_km);
    float mu_s = irradiance_mu_s_of_x(x.x);
    // E = integral over the upper hemisphere of L(omega) cos(theta) d omega; 32 zenith-angle
    // steps of 5.6 deg (in twilight the light comes from low over the horizon toward the sun).
    const int NT = 32;
    float dphi = ATMO_PI / float(NT);
    float dtheta = ATMO_PI / float(NT);
    vec3 omega_s = vec3(safe_sqrt(1.0 - mu_s * mu_s), 0.0, mu_s);
    vec3 result = vec3(0.0);
    for (int j = 0; j < NT / 2; ++j) {
        float theta = (float(j) + 0.5) * dtheta;
        for (int i = 0; i < 2 * NT; ++i) {
            float phi = (float(i) + 0.5) * dphi;
            vec3 w = vec3(cos(phi) * sin(theta), sin(phi) * sin(theta), cos(theta));
            float domega = dtheta * dphi * sin(theta);
            result += scattering_of_order(r, w.z, mu_s, dot(w, omega_s), false, u_order, true) * w.z * domega;
        }
    }
    imageStore(u_out_delta, texel, vec4(result, 0.0));
    imageStore(u_accumulate, texel, imageLoad(u_accumulate, texel) + vec4(result, 0.0));
}

#elif defined(STAGE_MULTIPLE_SCATTERING)
layout(binding = 0, rgba32f) uniform image3D u_out_delta;  // read: dS(n-1), then write dS(n)
layout(binding = 1, rgba32f) uniform image3D u_accumulate;
void main() {
    ivec3 texel = ivec3(gl_GlobalInvocationID) + ivec3(0, 0, u_z_offset);
    ivec3 size = imageSize(u_out_delta);
    if (any(greaterThanEqual(texel, size))) return;
    float r, mu, mu_s, nu;
    bool hits_ground;
    scattering_params(texel, size, r, mu, mu_s, nu, hits_ground);
    const int N = 32;
    float D = distance_to_nearest_boundary(r, mu, hits_ground);
    vec3 result = vec3(0.0);
    float d_prev = 0.0;
    for (int i = 0; i <= N; ++i) {
        float x = float(i) / float(N);
        float d = D * x * x;  // squeezed toward the observer, as in single scattering
        float r_i = clamp_radius(sqrt(d * d + 2.0 * r * mu * d + r * r));
        float mu_i = clamp_cosine((r * mu + d) / r_i);
        float mu_s_i = clamp_cosine((r * mu_s + d * nu) / r_i);
        vec3 j = scattering_lookup(u_delta_density_in, r_i, mu_i, mu_s_i, nu, hits_ground).rgb;
        float x_next = float(min(i + 1, N)) / float(N);
        float w = 0.5 * (D * x_next * x_next - d_prev);
        result += w * j * transmittance_segment(u_transmittance_in, r, mu, d, hits_ground);
        d_prev = d;
    }
    vec3 total = result;
    if (u_tail != 0) {
        // Last order computed: add the geometric tail of the orders not computed,
        // sum_{k>n} dS_k ~ dS_n q / (1 - q) with q = dS_n / dS_{n-1} per channel (clamped), so
        // that thick haze converges without ~20 orders (the series' ratio settles after 3-4).
        vec3 prev = imageLoad(u_out_delta, texel).rgb;
        vec3 q = clamp(result / max(prev, vec3(1e-30)), 0.0, 0.8);
        total = result / (1.0 - q);
    }
    imageStore(u_out_delta, texel, vec4(result, 0.0));
    imageStore(u_accumulate, texel, imageLoad(u_accumulate, texel) + vec4(total / rayleigh_phase(nu), 0.0));
}
#endif
