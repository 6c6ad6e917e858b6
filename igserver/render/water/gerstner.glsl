// Gerstner sea surface: the GLSL twin of igserver/water/surface.py (same symbols, same formulas).
// For a camera-relative rest point p (m) and wave i:
//   theta_i = k_i.p + phase_i + R_i(p)                 (phase_i: CPU-reduced k_i.cam - w_i t + phi_i)
//   a_i = A_i F_i(p) f_i,   b_i = min(Q(p) / (|K_i| n), a_i)
//   z1 = sum a_i sin theta_i,  z2 = (X^2 + Y^2 - sum s_i^2) / 2,  X + iY = sum s_i e^(i theta_i),
//   s_i = a_i sqrt(alpha |K_i|)       (second order: crests sharper than troughs)
//   P = (p + sum b_i Khat_i cos theta_i,  L(z1 + z2))   (L: the depth limit, bathymetry.depth_limit)
// f_i fades a wave out where the mesh spacing cannot carry it (LOD): waves of k*spacing between
// pi/2 and pi (4 to 2 vertices per wavelength); their slope variance goes to the roughness instead.
// Needs WATER_FOAM defined (water/foam.glsl, included first): without foam the lagged J is not summed.
#ifndef MAX_WAVES
#define MAX_WAVES 64
#endif

uniform int u_wave_count;
uniform vec4 u_wave[MAX_WAVES];         // xy: k_ref * D (rad/m), z: A (m), w: omega (rad/s)
uniform float u_wave_phase[MAX_WAVES];  // rad in [0, 2 pi)
uniform float u_wave_norm;              // n, the number of mesh waves
uniform float u_steepness;              // Q over the reference depth (no field)
uniform float u_second_order;           // alpha of z2 (surface.py; 0: linear Gerstner)
uniform float u_sea_depth;              // m, the depth limit's h (no field); <= 0: unlimited
uniform vec4 u_wave_lag[MAX_WAVES];     // per wave: 1 - cos(w lag), sin(w lag) for the foam's two lags (foam.py)

#ifdef WATER_FIELD
uniform sampler2DArray u_field;         // per wave: R (rad), F, Kx, Ky (rad/m)
uniform sampler2D u_field_scalar;       // Q(x), depth (m), breaking (0..1)
uniform vec2 u_field_origin;            // m, camera-relative position of node (0, 0)
uniform vec2 u_field_u;                 // unit axes
uniform vec2 u_field_v;
uniform vec2 u_field_cell;              // m, du, dv
uniform ivec2 u_field_size;             // nu, nv
#endif

struct SeaSample {
    vec3 pos;        // camera-relative displacement: xy displaced rest point, z height above mean level
    vec3 normal;
    float jacobian;  // horizontal Jacobian det(dP/dp): 1 flat, -> 0 where crests pinch (foam)
    float lost_var;  // slope variance of the waves faded out by the LOD
    float lost_jvar; // variance of J those waves would add (the foam's probability, water.frag.glsl)
    vec2 jacobian_past; // J at t - FOAM_LAG (foam.py): J + the first-order change, sum b k (sin th - sin(th + w lag))
    float depth;     // m (1e4 where no field: deep)
    float breaking;  // 0 unbroken .. 1: how much the breaking cap cut the waves (surf zone)
};

#ifdef WATER_FIELD
// Texture coordinate of the bilinear sample between node corners, exactly as water/field_sampling.py's
// _interpolate: the node grid clamped at its edges (texel centres, clamp-to-edge), one filtered
// fetch per wave instead of four texelFetch (the vertex shader's main cost on a CPU rasterizer).
vec2 field_uv(vec2 p) {
    vec2 d = p - u_field_origin;
    vec2 g = vec2(dot(d, u_field_u) / u_field_cell.x, dot(d, u_field_v) / u_field_cell.y);
    g = clamp(g, vec2(0.0), vec2(u_field_size - 1));
    if (u_field_size.y == 1) g.y = 0.0;
    return (g + 0.5) / vec2(u_field_size);
}
#endif

// The depth limit (bathymetry.depth_limit): the identity for |z| <= z0, then a tanh saturation toward
// +-c, c = 0.39 h (single waves <= 0.78 h), z0 = c / 2; returns L(z), and L'(z) in slope.
float depth_limit(float z, float h, out float slope) {
    float c = 0.39 * max(h, 1e-3);
    float z0 = 0.5 * c;
    float w = c - z0;
    float t = tanh(min(max(abs(z) - z0, 0.0) / w, 10.0));  // 10: tanh = 1 in float, no exp overflow
    slope = 1.0 - t * t;
    return sign(z) * (min(abs(z), z0) + w * t);
}

SeaSample sea_displace(vec2 p, float spacing) {
    float q = u_steepness;
    float depth = 1e4;
    float breaking = 0.0;
    float limit_depth = u_sea_depth > 0.0 ? u_sea_depth : 1e4;
#ifdef WATER_FIELD
    vec2 uv = field_uv(p);
    vec3 sc = textureLod(u_field_scalar, uv, 0.0).xyz;
    q = sc.x;
    depth = sc.y;
    breaking = sc.z;
    limit_depth = depth;
#endif
    vec2 disp = vec2(0.0);
    float height = 0.0;
    float jxx = 1.0, jxy = 0.0, jyx = 0.0, jyy = 1.0;
    vec2 grad = vec2(0.0);
    float lost = 0.0;
    float lost_j = 0.0;
    vec2 xy2 = vec2(0.0);   // X, Y
    vec2 gx2 = vec2(0.0);   // grad X = sum s K cos
    vec2 gy2 = vec2(0.0);   // -grad Y = sum s K sin
    float mean2 = 0.0;      // sum s^2
    vec2 lag = vec2(0.0);   // first-order J(t - lag) - J(t), both lags
    for (int i = 0; i < u_wave_count; ++i) {
        vec4 w = u_wave[i];
        float theta = dot(w.xy, p) + u_wave_phase[i];
        float a = w.z;
        vec2 kv = w.xy;
#ifdef WATER_FIELD
        vec4 f = textureLod(u_field, vec3(uv, float(i)), 0.0);
        theta += f.x;
        a *= f.y;
        kv = f.zw;
#endif
        float kmag = max(length(kv), 1e-12);
        float fade = 1.0 - smoothstep(0.5 * PI, PI, kmag * spacing);
        lost += (1.0 - fade) * 0.5 * (kmag * a) * (kmag * a);
        // To first order J = 1 - sum b k sin(theta): a wave faded from b_full to b takes
        // (b_full - b)^2 k^2 / 2 of J's variance with it.
        float b_full = min(q / (kmag * u_wave_norm), a);
        a *= fade;
        float b = min(q / (kmag * u_wave_norm), a);
        lost_j += 0.5 * (b_full - b) * (b_full - b) * kmag * kmag;
        float s = sin(theta), c = cos(theta);
        vec2 bk = (b / kmag) * kv;  // b * Khat
        disp += bk * c;
        height += a * s;
        jxx -= bk.x * s * kv.x;
        jxy -= bk.x * s * kv.y;
        jyx -= bk.y * s * kv.x;
        jyy -= bk.y * s * kv.y;
#if WATER_FOAM
        vec4 wl = u_wave_lag[i];  // theta(t - lag) = theta + w lag
        lag += dot(bk, kv) * (s * wl.xz - c * wl.yw);
#endif
        grad += a * c * kv;
        float s2 = a * sqrt(u_second_order * kmag);
        xy2 += s2 * vec2(s, c);
        gx2 += (s2 * c) * kv;
        gy2 += (s2 * s) * kv;
        mean2 += s2 * s2;
    }
    height += 0.5 * (dot(xy2, xy2) - mean2);
    grad += xy2.x * gx2 - xy2.y * gy2;
    float slope;
    height = depth_limit(height, limit_depth, slope);
    grad *= slope;
    vec3 tx = vec3(jxx, jyx, grad.x);
    vec3 ty = vec3(jxy, jyy, grad.y);
    SeaSample r;
    r.pos = vec3(p + disp, height);
    r.normal = normalize(cross(tx, ty));
    r.jacobian = jxx * jyy - jxy * jyx;
    r.lost_var = lost;
    r.lost_jvar = lost_j;
    r.jacobian_past = r.jacobian + lag;
    r.depth = depth;
    r.breaking = breaking;
    return r;
}
