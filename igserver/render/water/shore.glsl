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

// x: swash water cover (0..1), y: its front's foam (0..1), z: wet sand (0..1, up to the run-up's reach).
// Each wave's uprush takes 30 % of the period and its backwash the rest (swash on a gentle beach:
// Holthuijsen 2007, ch. 10; the uprush is the bore's fast run, the backwash drains slowly); each
// swash reaches 0.6-1.0 R2, varying from wave to wave and along the shore.
vec3 swash(vec2 p, float z) {
    float along = dot(p, u_swash_along.xy);
    float cycles = (u_swash.y - u_swash.z * along) / (2.0 * PI);
    float n = floor(cycles);
    float f = cycles - n;
    float vary = sin(u_swash_along.z * along + u_swash_along.w + 2.4 * n);
    float reach = u_swash.x * (0.8 + 0.2 * vary);
    float up = f < 0.3 ? smoothstep(0.0, 1.0, f / 0.3) : 1.0 - smoothstep(0.0, 1.0, (f - 0.3) / 0.7);
    float eta = reach * up;  // the swash front's height above the still water level
    float e = max(fwidth(z), 0.002);
    float cover = smoothstep(eta + e, eta - e, z);
    float front = cover * (1.0 - smoothstep(0.0, 0.25 * reach + e, eta - z)) * (f < 0.3 ? 0.9 : 0.35);
    float top = u_swash.x * (0.9 + 0.1 * sin(u_swash_along.z * along + u_swash_along.w));
    float wet = 1.0 - smoothstep(0.75 * top, top, z);
    return vec3(cover, front, wet);
}
