// The beach (docs/water.md#the-shore), for water.frag.glsl over a bathymetry field: the swash that runs
// up the sand and back with each wave, its white front, and the wet sand it leaves (shore.py sets the
// uniforms). The still water's edge is the contour h = 0; the swash moves it up to the run-up R2.

uniform vec4 u_shore_plane;  // xy: unit toward the shore; z: m, the shoreline's distance from the camera
                             // along it; w: beach slope (0: a height map, the land's height is -depth)
uniform vec4 u_swash;        // x: run-up R2 (m above the still water level), y: swash phase at the
                             // camera (rad, w t - k_y y_cam mod 2 pi), z: k_y (rad/m, along the shore), w: unused
uniform vec4 u_swash_along;  // xy: unit along the shore; z: k (rad/m) of the run-up's along-shore
                             // variation; w: its phase at the camera (rad)

uniform vec4 u_land;         // x: berm height (m), y: dune height (m), z: the camera's along-shore
                             // coordinate mod LAND_PERIOD (m), w: 1 where the land is drawn (a slope beach)

// m above the still water level at rest point p (< 0: under water). On a slope beach the plane itself
// (the field's grid ends a little past the shoreline, the swash runs further).
float shore_elevation(vec2 p, float depth) {
    return u_shore_plane.w > 0.0 ? u_shore_plane.w * (dot(p, u_shore_plane.xy) - u_shore_plane.z) : -depth;
}

// The land behind a slope beach (water/land.py profile, the same formulas; docs/water.md#the-shore):
// the foreshore's plane up to the berm crest, a near-flat backshore, a foredune ridge whose height
// and distance vary along the shore. Returns (height m above the still water level, dz/ds, dz/dy) at
// s m inland of the still-water line and the world along-shore coordinate y (mod LAND_PERIOD).
const float LAND_PERIOD = 1000.0;
const float BACKSHORE_SLOPE = 0.005;
const float BACKSHORE_M = 40.0;
const float DUNE_RISE_M = 35.0;
const float DUNE_FALL_M = 80.0;
const float DUNE_LEE = 0.3;
vec3 land_profile(float s, float y) {
    float beta = u_shore_plane.w;
    float s_b = u_land.x / beta;
    float w = 2.0 * PI / LAND_PERIOD;
    float foot = s_b + BACKSHORE_M * (1.0 + 0.3 * sin(4.0 * w * y));
    float dfoot = BACKSHORE_M * 0.3 * 4.0 * w * cos(4.0 * w * y);
    float z = s <= s_b ? beta * s : u_land.x + BACKSHORE_SLOPE * (min(s, foot) - s_b);
    float dz_ds = s <= s_b ? beta : s <= foot ? BACKSHORE_SLOPE : 0.0;
    float dz_dy = s > foot && s > s_b ? BACKSHORE_SLOPE * dfoot : 0.0;
    float height = u_land.y * (1.0 + 0.2 * sin(6.0 * w * y + 0.7) + 0.1 * sin(17.0 * w * y + 2.1));
    float dheight = u_land.y * (0.2 * 6.0 * w * cos(6.0 * w * y + 0.7) + 0.1 * 17.0 * w * cos(17.0 * w * y + 2.1));
    float u = s - foot;
    float a = clamp(u / DUNE_RISE_M, 0.0, 1.0);
    float b = clamp((u - DUNE_RISE_M) / DUNE_FALL_M, 0.0, 1.0);
    float ridge = a * a * (3.0 - 2.0 * a) - DUNE_LEE * b * b * (3.0 - 2.0 * b);
    float dridge = 6.0 * a * (1.0 - a) / DUNE_RISE_M - DUNE_LEE * 6.0 * b * (1.0 - b) / DUNE_FALL_M;  // d/du
    return vec3(z + height * ridge, dz_ds + height * dridge, dz_dy + dheight * ridge - height * dridge * dfoot);
}

// How far up the dune's rise s lies (0 at its foot and before, 1 from its crest on): where the dune
// grass grows (foredunes are held by marram grass; the backshore and the beach are bare sand).
float dune_rise(float s, float y) {
    float s_b = u_land.x / u_shore_plane.w;
    float foot = s_b + BACKSHORE_M * (1.0 + 0.3 * sin(4.0 * (2.0 * PI / LAND_PERIOD) * y));
    return clamp((s - foot) / DUNE_RISE_M, 0.0, 1.0);
}

// (s, y) of rest point p (camera-relative, m): inland distance and world along-shore coordinate.
vec2 land_coordinates(vec2 p) {
    return vec2(dot(p, u_shore_plane.xy) - u_shore_plane.z, mod(dot(p, u_swash_along.xy) + u_land.z, LAND_PERIOD));
}

// m the land rises above the still water level at rest point p (0 offshore, or without a slope beach).
float land_height(vec2 p) {
    if (u_land.w <= 0.0) return 0.0;
    vec2 sy = land_coordinates(p);
    return sy.x > 0.0 ? land_profile(sy.x, sy.y).x : 0.0;
}

// Per vertex (smooth over the mesh: the swash varies over tens of metres), at rest point p: x the
// swash front's height above the still water level (m), y the run-up's reach on this stretch of shore
// (the wet sand's top, m), z the front's foam (brighter in the uprush), w the front foam's depth (m).
// Each wave's uprush takes 30 % of the period and its backwash the rest (swash on a gentle beach:
// Holthuijsen 2007, ch. 10; the uprush is the bore's fast run, the backwash drains slowly); each
// swash reaches 0.6-1.0 R2, varying from wave to wave and along the shore.
vec4 swash_vertex(vec2 p) {
    float along = dot(p, u_swash_along.xy);
    float cycles = (u_swash.y - u_swash.z * along) / (2.0 * PI);
    float n = floor(cycles);
    float f = cycles - n;
    float reach = u_swash.x * (0.8 + 0.2 * sin(u_swash_along.z * along + u_swash_along.w + 2.4 * n));
    float up = f < 0.3 ? smoothstep(0.0, 1.0, f / 0.3) : 1.0 - smoothstep(0.0, 1.0, (f - 0.3) / 0.7);
    float top = u_swash.x * (0.9 + 0.1 * sin(u_swash_along.z * along + u_swash_along.w));
    return vec4(reach * up, top, f < 0.3 ? 0.9 : 0.35, 0.25 * reach);
}

// Per fragment, at height z above the still water level (z_step: fwidth(z)): x the swash's water
// cover (0..1), y its front's foam (0..1), z wet sand (0..1, up to the run-up's reach).
vec3 swash(vec4 s, float z, float z_step) {
    float e = max(z_step, 0.002);
    float cover = smoothstep(s.x + e, s.x - e, z);
    float front = cover * (1.0 - smoothstep(0.0, s.w + e, s.x - z)) * s.z;
    return vec3(cover, front, 1.0 - smoothstep(0.75 * s.y, s.y, z));
}
