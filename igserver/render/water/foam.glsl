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

// WATER_FOAM 0: a sea too calm for whitecaps (foam.py foam_drawn), its program without the foam's code
// (the lagged Jacobians, the mean cover, the dither): llvmpipe runs it on every pixel whatever it draws.
#ifndef WATER_FOAM
#define WATER_FOAM 1
#endif
uniform float u_foam_jacobian;  // J below which the sea turns white (foam.py drawn_foam_threshold)
uniform vec2 u_foam_edge;       // J above / below it where the foam starts / is solid (foam.py FOAM_EDGE)
uniform vec4 u_foam_decay;      // opacity of the foam FOAM_LAG[0], FOAM_LAG[1] seconds old; surf J threshold;
                                // opacity of the wind-row streaks everywhere (foam.py streak_opacity)
uniform vec2 u_foam_unresolved; // J centre of the unresolved foam's tail; its fresh share (foam.py foam_calibration)
uniform vec2 u_spray;           // x: spray strength (0..1, from the wind), y: 1 / Hs (1/m)

const float FOAM_SOFT = 0.5;    // the dither ramp's width in opacity (foam.py FOAM_SOFT)
const vec3 FOAM_FRESH = vec3(0.75);  // albedo of fresh, dense foam
const float FOAM_OLD = 0.5;          // opacity of old, thinned foam: the sea's grey-green shows through (foam.py)

// The dither's mean at opacity f through a ramp of width w (foam.py foam_mean): E over u uniform on
// [0, 1] of clamp((f - (1 - w) u) / w, 0, 1), w <= 0.5.
float foam_mean_ramp(float f, float w) {
    float covered = f < w ? f * f / (2.0 * w)
                  : f <= 1.0 - w ? f - 0.5 * w
                  : (f - w) + (w * w - (f - 1.0 + w) * (f - 1.0 + w)) / (2.0 * w);
    return covered / (1.0 - w);
}
float foam_mean(float f) { return foam_mean_ramp(f, FOAM_SOFT); }

// The foam at a vertex where the LOD faded some waves out of the mesh: J is then about normal about
// the mesh's J with the faded waves' variance (lost_jvar), widening the J edge to width2. The share r
// of the width the faded waves make blends two means. Resolved (r = 0): the foam of opacity d p, p
// the soft edge's fraction, its dither mean foam_mean(d p) — now, FOAM_LAG seconds ago (older, fainter)
// and the wind rows, the strongest (foam.py foam_cover_and_freshness). Unresolved (r = 1): the chance
// that J is under the centre foam.py calibrated for it (u_foam_unresolved: the same brightness-weighted
// mean over the sea, the resolved foam's share of fresh foam), the normal tail (Polya 1949: 0.5 (1 +
// sqrt(1 - exp(-2 z^2 / pi))), z = 2.2 x; within x1.6 of it to 3 sigma: a sparse sea's whitecaps are
// all in the tail). foam_mean(p) of a chance p would thin a sparse sea's foam out (0.8 % at Beaufort 5
// drew as 0.003 %), and interpolating J then thresholding it lost the low tail the same way.
float foam_resolved(float j, float centre, float width2, float d) {
    return foam_mean(d * smoothstep(-1.0, 1.0, (centre - j) * inversesqrt(width2)));
}

// x: mean cover (the dither's mean), y: freshness (the share of it from foam now), z: how much of a
// crest the point is (height 0.25 .. 0.75 Hs above the mean level: where spindrift leaves the sea).
// breaking (0..1, surf zone): the broken water is white where the crest is compressed at all
// (threshold raised toward u_foam_decay.z).
vec3 foam_vertex(float j, vec2 j_past, float lost_jvar, float breaking, float height) {
    float surf = smoothstep(0.1, 0.7, breaking);
    float shift = 0.5 * (u_foam_edge.x - u_foam_edge.y);  // edge centre - threshold
    float centre = mix(u_foam_jacobian, u_foam_decay.z, surf) + shift;
    float edge2 = 0.25 * (u_foam_edge.x + u_foam_edge.y) * (u_foam_edge.x + u_foam_edge.y);
    float width2 = edge2 + 4.84 * lost_jvar;
    float now = foam_resolved(j, centre, width2, 1.0);
    float resolved = max(max(now, foam_resolved(j_past.x, centre, width2, u_foam_decay.x)),
                         max(foam_resolved(j_past.y, centre, width2, u_foam_decay.y), foam_mean(u_foam_decay.w)));
    float x = (mix(u_foam_unresolved.x, u_foam_decay.z + shift, surf) - j) * inversesqrt(width2);
    float unresolved = 0.5 + 0.5 * sign(x) * sqrt(1.0 - exp(-3.08 * x * x));
    float r = 1.0 - edge2 / width2;
    float m = mix(resolved, max(unresolved, foam_mean(u_foam_decay.w)), r);  // the wind rows either way
    float fresh = mix(now, u_foam_unresolved.y * unresolved, r);
    return vec3(m, m > 1e-6 ? fresh / m : 1.0, smoothstep(0.25, 0.75, height * u_spray.y));
}
