// The beach (docs/water.md#the-shore), for water.frag.glsl over a bathymetry field: the swash that runs
// up the sand and back with each wave, its white front, and the wet sand it leaves (shore.py sets the
// uniforms). The still water's edge is the contour h = 0; the swash moves it up to the run-up R2.

uniform vec4 u_shore_plane;  // xy: unit toward the shore; z: m, the shoreline's distance from the camera
                             // along it; w: beach slope (0: a height map, the land's height is -depth)
uniform vec4 u_swash;        // x: run-up R2 (m above the still water level), y: swash phase at the
                             // camera (rad, w t - k_y y_cam mod 2 pi), z: k_y (rad/m, along the shore), w: unused
uniform vec4 u_swash_along;  // xy: unit along the shore; z: k (rad/m) of the run-up's along-shore
                             // variation; w: its phase at the camera (rad)

// m above the still water level at rest point p (< 0: under water). On a slope beach the plane itself
// (the field's grid ends a little past the shoreline, the swash runs further).
float shore_elevation(vec2 p, float depth) {
    return u_shore_plane.w > 0.0 ? u_shore_plane.w * (dot(p, u_shore_plane.xy) - u_shore_plane.z) : -depth;
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
