// Sea foam (docs/water.md#foam), shared by water.vert.glsl (coverage per vertex) and water.frag.glsl
// (streaks, colour, spray). The mirror of foam.py (foam_coverage): change both together.
//
// Per vertex: the probability that the surface is whitecap now and FOAM_LAG seconds ago (J at the
// same rest point, i.e. the same water particle, at t - lag: gerstner.glsl jacobian_past), the older
// foam fading as exp(-lag / FOAM_DECAY_S). The vertex hands on the foam's MEAN cover (foam_mean of the
// opacity) and its freshness: linear interpolation keeps the mean of the vertices' values over the
// triangle, so the coverage survives a coarse mesh and minification (interpolating J and then
// thresholding thins the rare low-J tail out: distant whitecaps vanished). The fragment inverts
// foam_mean and dithers the opacity into wind streaks of that mean.

uniform float u_foam_jacobian;  // J below which the sea turns white (foam.py drawn_foam_threshold)
uniform vec2 u_foam_edge;       // J above / below it where the foam starts / is solid (foam.py FOAM_EDGE)
uniform vec4 u_foam_decay;      // opacity of the foam FOAM_LAG[0], FOAM_LAG[1] seconds old; surf J threshold;
                                // opacity of the wind-row streaks everywhere (foam.py streak_opacity)
uniform vec2 u_spray;           // x: spray strength (0..1, from the wind), y: 1 / Hs (1/m)

const float FOAM_SOFT = 0.25;   // the dither ramp's width in opacity (foam.py FOAM_SOFT)
const vec3 FOAM_FRESH = vec3(0.75);  // albedo of fresh, dense foam
const float FOAM_OLD = 0.5;          // opacity of old, thinned foam: the sea's grey-green shows through (foam.py)

float foam_mean(float f) {
    float w = FOAM_SOFT;
    float covered = f < w ? f * f / (2.0 * w)
                  : f <= 1.0 - w ? f - 0.5 * w
                  : (f - w) + (w * w - (f - 1.0 + w) * (f - 1.0 + w)) / (2.0 * w);
    return covered / (1.0 - w);
}

// The opacity f whose dither mean is m (foam_mean is increasing: piecewise quadratic, linear, quadratic).
float foam_mean_inverse(float m) {
    float w = FOAM_SOFT;
    float c = clamp(m, 0.0, 1.0) * (1.0 - w);  // the covered part
    float lo = 0.5 * w;                           // covered at f = w
    if (c < lo) return sqrt(2.0 * w * c);
    if (c <= 1.0 - 1.5 * w) return c + 0.5 * w;
    return 1.0 - sqrt(max(2.0 * w * (1.0 - w - c), 0.0));
}

// The mean cover of foam of opacity d where J is below the threshold t, given the mesh's J and the
// J variance of the waves the LOD faded out: the probability p of J under the soft edge (a normal
// CDF: smoothstep over +-2.2 sigma follows it within 0.03). Where the edge is resolved (no faded
// waves) the opacity is d p itself, its dither mean foam_mean(d p); where the faded waves make the
// width, p is the chance of foam of opacity d at this point, its mean p foam_mean(d) — foam_mean(d p)
// there would thin a sparse sea's whitecaps out (0.8 % at Beaufort 5 drew as 0.003 %).
// x: the resolved mean, y: the unresolved one (see above); z: the unresolved share of the width.
vec3 foam_term(float j, float t, float lost_jvar, float d) {
    float centre = t + 0.5 * (u_foam_edge.x - u_foam_edge.y);
    float edge2 = 0.25 * (u_foam_edge.x + u_foam_edge.y) * (u_foam_edge.x + u_foam_edge.y);
    float width2 = edge2 + 4.84 * lost_jvar;
    float x = (centre - j) * inversesqrt(width2);  // in units of 2.2 sigma
    float p = smoothstep(-1.0, 1.0, x);
    // the normal CDF's tail (Polya 1949: 0.5 (1 + sqrt(1 - exp(-2 z^2 / pi))), z = 2.2 x; within x1.6
    // of it to 3 sigma): a sparse sea's whitecaps are all in the tail
    float tail = 0.5 + 0.5 * sign(x) * sqrt(1.0 - exp(-3.08 * x * x));
    return vec3(foam_mean(d * p), tail * foam_mean(d), 1.0 - edge2 / width2);
}

// x: mean cover (the dither's mean), y: freshness (the share of it from foam now), z: how much of a
// crest the point is (height 0.25 .. 0.75 Hs above the mean level: where spindrift leaves the sea).
// breaking (0..1, surf zone): the broken water is white where the crest is compressed at all
// (threshold raised toward u_foam_decay.z). Resolved, the foam at a point is the strongest of the
// fresh, the older and the wind rows' (foam.py foam_coverage); unresolved, the chances of each at
// the point are about independent (the lags are a good part of a wave period apart): their union.
vec3 foam_vertex(float j, vec2 j_past, float lost_jvar, float breaking, float height) {
    float t = mix(u_foam_jacobian, u_foam_decay.z, smoothstep(0.1, 0.7, breaking));
    vec3 now = foam_term(j, t, lost_jvar, 1.0);
    vec3 old1 = foam_term(j_past.x, t, lost_jvar, u_foam_decay.x);
    vec3 old2 = foam_term(j_past.y, t, lost_jvar, u_foam_decay.y);
    float rows = foam_mean(u_foam_decay.w);
    float resolved = max(max(now.x, old1.x), max(old2.x, rows));
    float unresolved = 1.0 - (1.0 - now.y) * (1.0 - old1.y) * (1.0 - old2.y) * (1.0 - rows);
    float m = mix(resolved, unresolved, now.z);
    float fresh = mix(now.x, now.y, now.z);
    return vec3(m, m > 1e-6 ? fresh / m : 1.0, smoothstep(0.25, 0.75, height * u_spray.y));
}
