// The foam's pattern per pixel (docs/water.md#shading, Whitecaps): the vertex's mean cover m
// (foam.glsl foam_vertex) dithered into streaks and patches with the same mean. Needs
// generated/bindings.glsl and foam.glsl (u_spray).
//
// The dither is a threshold on a standard normal noise Z: foam where Z < t = Phi^-1(m), so the
// mean over the noise is m. Z is a sum of independent lookups of the tabulated noise (z about
// N(0, 1): water/foam_noise.frag.glsl), anchored to the world and drifting downwind with the surface:
// - streaks (the old foam): three octaves, cells along x across the wind of the finest
//   (foam.py streak_size: longer the stronger the wind) times FOAM_OCTAVE_SCALE — thin streaks
//   bunched, from Beaufort 7, into wider and longer wind rows (foam.py streak_octave_weights), so
//   the pattern is still streaks where the finest octave is below a pixel;
// - patches (fresh whitecaps drawn out downwind, foam.py FOAM_PATCH_SIZE);
// weighted by the foam's freshness. An octave fades as a pixel spans more of its cells (contrast 1
// up to 1/4 cell, 0 from 3/4: past that it would alias); what has faded is unknown noise of the
// same variance, so the pixel draws the foam's expected cover given the octaves it shows:
// Phi((t s - z_v) / sigma), sigma^2 the faded variance plus the ramp's e^2 (the pixel's own
// spread of z_v: anti-aliasing; for old foam at least FOAM_RAMP_OLD, so streaks end softly) and
// s = sqrt(1 + e^2), which keeps the mean m for every fade. With every octave faded it is m itself.

uniform vec4 u_foam_frame;      // xy: unit downwind direction; zw: 1 / length, 1 / width of the finest streak cell (1/m)
uniform vec2 u_foam_offset[2];  // the camera's noise coordinates, drifted downwind, mod FOAM_PERIOD (CPU): the finest
                                // octave's lookup, the rows' (in the first coarse octave's cells)
uniform vec4 u_foam_patch;      // the fresh foam's noise: 1 / cell length, 1 / width (1/m), camera's coordinates
uniform float u_foam_period;    // noise cells per side of the tabulated noise
// 0.5 + z / 8 per channel, z about N(0, 1) (water/foam_noise.frag.glsl): r in the table's cells, g and b
// in cells of FOAM_OCTAVE_SCALE_2 / FOAM_OCTAVE_SCALE_1 and of the meander's (foam.py rows_channel_cells)
layout(binding = UNIT_FOAM_NOISE) uniform sampler2D u_foam_noise;

uniform vec3 u_foam_octaves;    // per streak octave its weight in Z, the squares summing to 1 (foam.py streak_octave_weights)
// Per coarser octave its cell's length and width over the finest's (foam.py FOAM_OCTAVE_SCALE).
const vec2 FOAM_OCTAVE_SCALE_1 = vec2(8.0, 4.0), FOAM_OCTAVE_SCALE_2 = vec2(16.0, 16.0);
const float FOAM_MEANDER = 4.0;  // finest cells the streaks wander per unit of the meander noise (rows at full weight: x 0.5)
const float FOAM_NOISE_SLOPE = 4.8;  // z per noise cell: the tabulated noise's rms gradient along x or y (measured)
const float FOAM_RAMP_OLD = 0.1;     // the old foam's least ramp in z (soft streak ends); fresh foam's 0.05
const float SPRAY_MEAN = 0.375;      // mean of smoothstep(0.35, 0.9, u), u uniform on [0, 1]

// Bilinear filtering between texels 1/8 cell apart (correlated 0.82: the noise's gradient) lowers
// the noise's standard deviation between them, to 0.92 on average (measured): FOAM_Z_GAIN restores it.
// The second and third channels' cells span 16 x 32 and 16 x 128 texels: their bilinear samples keep
// 0.98 of it (measured), FOAM_ROWS_GAIN.
const float FOAM_Z_GAIN = 1.087;
const vec3 FOAM_ROWS_GAIN = vec3(FOAM_Z_GAIN, 1.02, 1.02);
float foam_z(vec2 q) {
    // no mipmaps (a trilinear fetch costs 2x): the pattern has faded before a pixel spans 6 texels
    return FOAM_Z_GAIN * (8.0 * textureLod(u_foam_noise, q / u_foam_period, 0.0).r - 4.0);
}
// The wind rows' noises at q, the first coarse octave's cells: that octave's z, the coarsest's z and
// the meander's, from one lookup of the three channels.
vec3 foam_rows(vec2 q) {
    return FOAM_ROWS_GAIN * (8.0 * textureLod(u_foam_noise, q / u_foam_period, 0.0).rgb - 4.0);
}
// The standard normal CDF: erfc by Abramowitz & Stegun 7.1.26 (absolute error 1.5e-7, the relative
// error small in the tails too: a polynomial times exp(-x^2)).
float foam_phi(float x) {
    float a = abs(x) * 0.70710678;
    float t = 1.0 / (1.0 + 0.3275911 * a);
    float tail = 0.5 * t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027
                 + t * 1.061405429)))) * exp(-a * a);  // Phi(-|x|)
    return x < 0.0 ? tail : 1.0 - tail;
}
// Its inverse: sqrt(2) erfinv(2p - 1), erfinv by Giles (2010, single precision: relative error 4e-7).
float foam_phi_inverse(float p) {
    float x = 2.0 * clamp(p, 1e-6, 1.0 - 1e-6) - 1.0;
    float w = -log((1.0 - x) * (1.0 + x)), q;
    if (w < 5.0) {
        w -= 2.5;
        q = 2.81022636e-08;
        q = 3.43273939e-07 + q * w; q = -3.5233877e-06 + q * w; q = -4.39150654e-06 + q * w;
        q = 0.00021858087 + q * w; q = -0.00125372503 + q * w; q = -0.00417768164 + q * w;
        q = 0.246640727 + q * w; q = 1.50140941 + q * w;
    } else {
        w = sqrt(w) - 3.0;
        q = -0.000200214257;
        q = 0.000100950558 + q * w; q = 0.00134934322 + q * w; q = -0.00367342844 + q * w;
        q = 0.00573950773 + q * w; q = -0.0076224613 + q * w; q = 0.00943887047 + q * w;
        q = 1.00167406 + q * w; q = 2.83297682 + q * w;
    }
    return 1.41421356 * q * x;
}
// An octave's contrast at `cells`, the noise cells a pixel spans.
float foam_fade(float cells) { return clamp(1.5 - 2.0 * cells, 0.0, 1.0); }

// The rest point in noise cells along and across the wind (inv_size: 1 / cell length, 1 / width)
// and the cells a pixel spans (|fwidth|, from the rest point's screen derivatives dx, dy: q is
// linear in the rest point).
vec2 foam_cells(vec2 rest, vec2 dx, vec2 dy, vec2 inv_size, out vec2 width) {
    mat2 to_cells = mat2(u_foam_frame.x * inv_size.x, -u_foam_frame.y * inv_size.y,
                         u_foam_frame.y * inv_size.x, u_foam_frame.x * inv_size.y);  // columns: x, y of the rest point
    width = abs(to_cells * dx) + abs(to_cells * dy);
    return to_cells * rest;
}

// Whitecaps a pixel cannot resolve (docs/water.md#shading, Whitecaps far away): where the patches'
// noise has faded, the foam used to be its mean m, an even grey veil, though a real sea's whitecaps are
// sparse: in a pixel of the far sea there are a few or none. There the pixel's foam is the whitecaps
// that fall into a world-fixed cell of about the pixel's extent: with a whitecap covering
// FOAM_DOT_AREA of a patch cell, a cell of n patch cells holds lambda = m n / FOAM_DOT_AREA of them on
// average; it shows foam with a chance P = lambda / (1 + lambda) (about lambda when sparse, 1 when
// dense), and then m / P of it (FOAM_DOT_AREA / n + m: under 1), so the mean stays m. Each cell
// breaks afresh every FOAM_DOT_LIFE seconds at its own phase and its foam fades over the life toward
// 3 (1 - age)^2 (mean 1, so the mean is again m; less of that swing where it would pass full cover);
// the draw against P goes through a ramp, so a dot fades in and out as the waves move m. The cells
// drift downwind with the patches (foam.py foam_frame u_foam_dots). Only a sea without wind rows
// (WATER_FOAM_DOTS): a storm's foam is dense, its dots would be its mean.
#if WATER_FOAM_DOTS
uniform vec3 u_foam_dots;  // xy: the camera's patch-cell coordinates, drifted, mod FOAM_DOT_PERIOD; z: time (s) mod
                           // FOAM_DOT_LIFE x 4096 (foam.py foam_frame)
// FOAM_DOT_AREA (a whitecap's area over its patch cell), FOAM_DOT_LIFE (s between two breakings of a
// cell), FOAM_DOT_PERIOD (patch cells the cells' coordinates wrap on, a power of two): defined by
// water.py from foam.py's values (foam.py dots_defines).

// The whitecaps of mean cover m at the rest point (m; dx, dy its screen derivatives; sparse: 1 for the
// open sea's whitecaps, 0 for the surf's foam, which lies in lines along the breaking crests), in the cell of
// 2^level.x by 2^level.y patch cells (along, across the wind) that matches the pixel's extent along and
// across the wind (seen at a grazing angle a pixel is long in depth and narrow, so a whitecap far off
// is a short dash along the horizon, as a breaking crest foreshortened is). From where the patches
// have faded (a pixel spans 3/4 of a patch cell) the dots come in, whole from 1.5 cells.
float foam_dots(float m, vec2 rest, vec2 dx, vec2 dy, float sparse) {
    vec2 extent;
    vec2 q = foam_cells(rest, dx, dy, u_foam_patch.xy, extent) + u_foam_dots.xy;
    // no dots where the derivatives run off (a silhouette at the horizon: NaN would reach the picture)
    // or the interpolated mean dips under 0
    if (!(max(extent.x, extent.y) < 1e30) || !(m > 0.0)) return m;
    // the level per axis: the exponent of the pixel's extent in patch cells, rounded (frexp: x = f 2^e,
    // f in [0.5, 1); 1.4 cells and up -> level 1, from 2.8 level 2, ...)
    ivec2 level;
    frexp(clamp(extent, vec2(1.0), vec2(FOAM_DOT_PERIOD)) * 0.7071068, level);  // at the horizon extents run off
    // the cell: the patch cell's integer coordinates wrapped on FOAM_DOT_PERIOD (a power of two) and
    // shifted down by the level
    ivec2 cell = (ivec2(floor(q)) & (FOAM_DOT_PERIOD - 1)) >> level;
    // one hash: the cell's phase (high bits), then a fresh draw per life (the low bits scrambled with
    // the life's number: one multiply)
    uint h = uint(cell.x) * 0x8da6b343u ^ uint(cell.y) * 0xd8163841u ^ uint(level.x + 16 * level.y) * 0xcb1ab31fu;
    h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15;
    float age = u_foam_dots.z / FOAM_DOT_LIFE + float(h >> 16) * (1.0 / 65536.0);
    float life = floor(age);
    uint k = ((h & 0xffffu) ^ (uint(life) * 0x9e3779b9u)) * 0x85ebca6bu;
    float lambda = m * float(1 << (level.x + level.y)) / FOAM_DOT_AREA;
    float p = lambda / (1.0 + lambda);  // the chance the cell shows foam: ~lambda when sparse, 1 when dense
    float cover = min(m / max(p, 1e-9), 1.0);  // = FOAM_DOT_AREA / n + m: under 1 unless m is near 1
    // the foam's fading over a life, 3 (1 - age)^2, mean 1: a sparse cell's one whitecap ages, a dense
    // cell's lambda whitecaps of their own ages average out (by 1 / sqrt(1 + lambda) = sqrt(1 - P)); no
    // more than keeps the cover under 1
    float x = age - life;
    float fading = clamp(0.5 * (1.0 / max(cover, 1e-9) - 1.0), 0.0, 1.0) * sqrt(1.0 - p);
    float decay = 1.0 + fading * (3.0 * (1.0 - x) * (1.0 - x) - 1.0);
    // shown where the cell's draw u is under p, through a ramp p (1 - p) wide centred on p (its mean
    // over u is still p): a dot fades in and out as the waves move m, instead of popping
    float u = float(k >> 16) * (1.0 / 65536.0);
    float shown = clamp((p - u) / max(p * (1.0 - p), 1e-6) + 0.5, 0.0, 1.0);
    float dots = shown * cover * decay;
    return mix(m, dots, smoothstep(0.75, 1.5, max(extent.x, extent.y)) * sparse);
}
#endif

#if WATER_FOAM_STREAKS
// The lookups only where there is foam (or spray) with a pattern that has not faded, in branches a GPU
// skips where all of a group of pixels agrees; llvmpipe runs a fragment shader's branches masked, every
// lookup compiled in on every pixel, so for it the program variants (WATER_FOAM_STREAKS) and the rows'
// one lookup of three channels are what keep the cost down. The derivatives come from main (the detail
// maps' too), outside any branch.
// rest: the rest point (m), dx and dy its screen derivatives; sparse: the share of the foam that is the open
// sea's whitecaps (not the surf's lines: foam_dots).
float foam_cover(float m, float fresh, vec2 rest, vec2 dx, vec2 dy, float sparse, out float spray) {
    vec2 w_streak, w_patch;
    vec2 q_streak = foam_cells(rest, dx, dy, u_foam_frame.zw, w_streak);
    vec2 q_patch = foam_cells(rest, dx, dy, u_foam_patch.xy, w_patch) + u_foam_patch.zw;
    float old = 1.0 - fresh;
    float norm = inversesqrt(old * old + fresh * fresh);  // Z's parts (1 - fresh) streaks + fresh patches, variance 1
    // per lookup (the streak octaves, the patches): the cells a pixel spans, the weight in Z it shows
    vec4 cells = vec4(length(w_streak), length(w_streak / FOAM_OCTAVE_SCALE_1), length(w_streak / FOAM_OCTAVE_SCALE_2),
                      length(w_patch));
#if WATER_FOAM_STREAKS >= 2
    vec3 octaves = u_foam_octaves;
#else  // no wind rows this frame (foam.py streak_variant): the coarser octaves' code left out
    vec3 octaves = vec3(1.0, 0.0, 0.0);
#endif
    vec4 weight = vec4(old * norm * octaves, fresh * norm) * clamp(1.5 - 2.0 * cells, 0.0, 1.0);
    float shown = dot(weight, weight);  // variance of the shown lookups in Z
    float c_streak = foam_fade(cells.x);
    // the normal tail is never quite 0: below 1e-4, or where the pattern has faded, the foam is its mean
    bool foamy = m > 1e-4 && shown > 0.0;
    float cover = m;
    spray = SPRAY_MEAN;
    if (foamy || (u_spray.x > 0.0 && c_streak > 0.0)) {
        vec4 z = vec4(0.0);
#if WATER_FOAM_STREAKS >= 2
        // the rows (coarse octaves) and the meander: storm streaks wander, the finest octave's
        // across-wind coordinate shifted by a noise of larger cells fixed on the sea like the octaves
        // (FOAM_MEANDER finest cells a unit of it)
        vec3 rows = foam_rows(q_streak / FOAM_OCTAVE_SCALE_1 + u_foam_offset[1]);
        z.yz = rows.xy;
        vec2 q0 = q_streak + u_foam_offset[0] + vec2(0.0, FOAM_MEANDER * u_foam_octaves.y * rows.z);
#else
        vec2 q0 = q_streak + u_foam_offset[0];
#endif
        // the finest octave where it shows (where it has faded, so have the spindrift's streaks)
        if (c_streak > 0.0) z.x = foam_z(q0);
        // spindrift between the streaks: the finest octave as a uniform variable (its normal CDF)
        spray = mix(SPRAY_MEAN, smoothstep(0.35, 0.9, 1.0 - smoothstep(-2.2, 2.2, z.x)), c_streak);
        if (foamy) {
            if (weight.w > 0.0) z.w = foam_z(q_patch);
            // the ramp: half the pixel's spread of z (its rms change over a pixel), at least the least ramp
            vec4 spread = weight * cells;
            float e2 = max(0.25 * FOAM_NOISE_SLOPE * FOAM_NOISE_SLOPE * dot(spread, spread),
                           pow(mix(FOAM_RAMP_OLD, 0.05, fresh), 2.0));
            float sigma = sqrt(max(1.0 - shown, 0.0) + e2);
            cover = foam_phi((foam_phi_inverse(m) * sqrt(1.0 + e2) - dot(weight, z)) / sigma);
        }
    }
#if WATER_FOAM_DOTS
    // where a pixel spans patch cells (the patches have faded), the whitecaps are sparse dots of the same mean
    if (m > 0.0) cover *= foam_dots(m, rest, dx, dy, sparse) / m;
#endif
    return cover;
}
#else  // a block where every pixel spans 3/4 of every noise cell (water.py foam_streaks_needed): the mean
float foam_cover(float m, float fresh, vec2 rest, vec2 dx, vec2 dy, float sparse, out float spray) {
    spray = SPRAY_MEAN;
#if WATER_FOAM_DOTS
    return foam_dots(m, rest, dx, dy, sparse);
#else
    return m;
#endif
}
#endif
