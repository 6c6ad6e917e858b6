// What the passes of the detail maps' synthesis share (detail_synth.py has the maths): the waves'
// phases at the frame's time and the grid of the levels' spectra and partial transforms.
//
// The phase φ = φ0 − ω t (mod 2π) is reduced in double precision as on the host (t reaches 1e9 s, where
// ω t ~ 1e10 rad: a float would keep no digit of the phase); only the reduced angle, in [−π, π), goes to
// float for its sine and cosine (an absolute rounding of 1.2e-7 rad).
#include "generated/bindings.glsl"

// Per wave of every map: (ω rad/s, φ0 rad at t = 0, m + n of its lattice point, unused).
layout(std430, binding = STORAGE_SEA_DETAIL_WAVES) readonly buffer DetailWaves { dvec4 detail_waves[]; };
// Complex values: the waves' phasors e^{iφ} (the first pass's), then per spectral level the rows that
// hold a bin (S values each, zero but on the bins, which the second pass writes) and its S × S grid
// (rows n, columns x) after the third pass's inverse DFT along m (its rows that hold no bin stay zero:
// no pass writes them).
layout(std430, binding = STORAGE_SEA_DETAIL_GRID) buffer DetailGrid { vec2 detail_grid[]; };
// The same as pairs of complex values, one load each: the rows' interleaved spectra.
layout(std430, binding = STORAGE_SEA_DETAIL_GRID) readonly buffer DetailGrid4 { vec4 detail_grid4[]; };

uniform double u_time;  // s

const double DETAIL_TWO_PI = 6.283185307179586LF;
const double DETAIL_PI = 3.141592653589793LF;

double detail_wrap(double x) {  // x mod 2π, in [0, 2π)
    return x - DETAIL_TWO_PI * floor(x * (1.0LF / DETAIL_TWO_PI));
}

double detail_phase(int wave) {  // φ = φ0 − ω t mod 2π, as detail.py detail_tiles
    dvec4 w = detail_waves[wave];
    return detail_wrap(w.y - detail_wrap(w.x * u_time));
}

float detail_angle(double x) {  // x mod 2π as a float in [−π, π)
    double r = detail_wrap(x);
    return float(r >= DETAIL_PI ? r - DETAIL_TWO_PI : r);
}
