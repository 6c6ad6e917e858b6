// The project's one noise implementation: 3D simplex noise on the lattice of Gustavson & McEwan
// 2022 ("psrdnoise"), written from the paper's description.
//
// Why not the classic 2012 simplex noise: its kernel radius (r^2 = 0.6) reaches past the simplex
// and leaves seams along simplex borders, and its 12-gradient set aligned with the axes shows
// diagonal streaks. Here:
//   * lattice: x -> uvw = M x with M = [[0,1,1],[1,0,1],[1,1,0]]; vertices back in x-space are
//     Mi i (Mi = M^-1, entries +-1/2), which makes every simplex the same shape;
//   * kernel (0.5 - |d|^2)^4, zero before the kernel of a non-neighbour vertex reaches in: no seams;
//   * gradients: an integer hash (no mod-289 repetition) mapped uniformly onto the unit sphere,
//     so no preferred directions;
//   * optional period per axis (any positive integer, 0 = none): vertices are wrapped in x-space,
//     v mod p, and re-indexed with i = M v, which stays integer. A time scroll along a periodic
//     axis can then be reduced on the CPU modulo the period without a visible jump.
// Output range is about [-1, 1] (scaled so the observed extremes are near +-1), mean 0.

// Guarded: both the cirrus and the fog relief (common/fog_relief.glsl) include it into the sky pass.
#ifndef NOISE_GLSL
#define NOISE_GLSL
uint noise_hash(ivec3 i, uint seed) {
    uvec3 v = uvec3(i) * uvec3(0x8da6b343u, 0xd8163841u, 0xcb1ab31fu);
    uint h = v.x ^ v.y ^ v.z ^ (seed * 0x9e3779b9u);
    // murmur3 finaliser: every input bit affects every output bit
    h ^= h >> 16; h *= 0x7feb352du;
    h ^= h >> 15; h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

// Uniform unit vector from 32 hash bits: z uniform in [-1,1] (Archimedes), azimuth uniform.
vec3 noise_gradient(uint h) {
    float z = 1.0 - 2.0 * (float(h & 0xffffu) + 0.5) * (1.0 / 65536.0);
    float phi = 6.28318530718 * float(h >> 16) * (1.0 / 65536.0);
    float r = sqrt(max(1.0 - z * z, 0.0));
    return vec3(r * cos(phi), r * sin(phi), z);
}

// The gradient of the lattice vertex at x-space position v (unwrapped): wrapped on the period,
// re-indexed on the lattice, hashed.
vec3 noise_vertex_gradient(vec3 v, vec3 period, uint seed) {
    const mat3 M = mat3(0.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0);
    vec3 vw = v;
    if (period.x > 0.0) vw.x = mod(vw.x, period.x);
    if (period.y > 0.0) vw.y = mod(vw.y, period.y);
    if (period.z > 0.0) vw.z = mod(vw.z, period.z);
    return noise_gradient(noise_hash(ivec3(round(M * vw)), seed));
}

// Contribution of one lattice vertex (x-space position v, unwrapped) to the point x.
float noise_corner(vec3 x, vec3 v, vec3 period, uint seed) {
    vec3 d = x - v;
    float w = max(0.5 - dot(d, d), 0.0);
    float w2 = w * w;
    return w2 * w2 * dot(noise_vertex_gradient(v, period, seed), d);
}

// The four vertices (x-space) of the simplex holding x.
void simplex3_vertices(vec3 x, out vec3 v0, out vec3 v1, out vec3 v2, out vec3 v3) {
    const mat3 M = mat3(0.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0);
    const mat3 Mi = mat3(-0.5, 0.5, 0.5, 0.5, -0.5, 0.5, 0.5, 0.5, -0.5);
    vec3 uvw = M * x;
    vec3 i0 = floor(uvw);
    vec3 f0 = uvw - i0;
    // Which simplex of the unit cube: walk from i0 to i0 + 1 along the components of f0 in
    // decreasing order. o1 = one-hot of the largest, o2 = the two largest.
    vec3 g_ = step(f0.xyx, f0.yzz);
    vec3 l_ = 1.0 - g_;
    vec3 g = vec3(l_.z, g_.xy);
    vec3 l = vec3(l_.xy, g_.z);
    vec3 o1 = min(g, l);
    vec3 o2 = max(g, l);
    v0 = Mi * i0;
    v1 = Mi * (i0 + o1);
    v2 = Mi * (i0 + o2);
    v3 = Mi * (i0 + 1.0);
}

float simplex3(vec3 x, vec3 period, uint seed) {
    vec3 v0, v1, v2, v3;
    simplex3_vertices(x, v0, v1, v2, v3);
    float n = noise_corner(x, v0, period, seed) + noise_corner(x, v1, period, seed)
            + noise_corner(x, v2, period, seed) + noise_corner(x, v3, period, seed);
    return 106.0 * n;  // 39.5 in psrdnoise for its gradient set; ours peaks at 0.364 * 39.5
}

// simplex3 and its gradient in one pass over the same four corners: (value, d/dx, d/dy, d/dz). A
// corner's term w^4 (g.d), w = 0.5 - d.d, d = x - v, has the gradient w^4 g - 8 w^3 (g.d) d.
vec4 noise_corner_grad(vec3 x, vec3 v, vec3 period, uint seed) {
    vec3 d = x - v;
    float w = max(0.5 - dot(d, d), 0.0);
    vec3 g = noise_vertex_gradient(v, period, seed);
    float w3 = w * w * w;
    float gd = dot(g, d);
    return vec4(w3 * w * gd, w3 * w * g - 8.0 * w3 * gd * d);
}

vec4 simplex3_grad(vec3 x, vec3 period, uint seed) {
    vec3 v0, v1, v2, v3;
    simplex3_vertices(x, v0, v1, v2, v3);
    return 106.0 * (noise_corner_grad(x, v0, period, seed) + noise_corner_grad(x, v1, period, seed)
                    + noise_corner_grad(x, v2, period, seed) + noise_corner_grad(x, v3, period, seed));
}

// Sum of octaves: Turb(P) = sum_{i<N} 0.5^i * simplex3(P * 2^i), with a different seed per octave.
// A period along an axis stays a period of the sum (octave i sees period * 2^i).
float turbulence3(vec3 p, vec3 period, int octaves, uint seed) {
    float sum = 0.0;
    float weight = 1.0;
    for (int i = 0; i < octaves; ++i) {
        sum += weight * simplex3(p, period, seed + uint(i) * 0x632be5abu);
        p *= 2.0;
        period *= 2.0;
        weight *= 0.5;
    }
    return sum;
}

// turbulence3 and its gradient (the same octaves and seeds: .x equals turbulence3's value).
vec4 turbulence3_grad(vec3 p, vec3 period, int octaves, uint seed) {
    vec4 sum = vec4(0.0);
    float weight = 1.0;
    float scale = 1.0;
    for (int i = 0; i < octaves; ++i) {
        vec4 n = simplex3_grad(p, period, seed + uint(i) * 0x632be5abu);
        sum += weight * vec4(n.x, n.yzw * scale);
        p *= 2.0;
        period *= 2.0;
        weight *= 0.5;
        scale *= 2.0;
    }
    return sum;
}
#endif  // NOISE_GLSL
