// Sea mesh: one instanced G x G patch per CDLOD block (lod.py), morphed, displaced, on the earth.
#include "common/frame.glsl"
#include "water/sea_tables.glsl"
#include "water/foam.glsl"
#include "water/gerstner.glsl"
#ifdef WATER_FIELD
#include "water/shore.glsl"
out vec4 v_swash;              // the swash on the beach (shore.glsl swash_vertex)
#endif

uniform vec2 u_morph[24];      // per level: morph start, end distance (m)
uniform float u_patch_quads;   // G
uniform float u_cam_height;    // m, camera height above the mean sea level
uniform float u_level_z;       // m, camera-relative z of the mean sea level

in vec2 in_grid;               // vertex (i, j), 0..G
in vec4 in_node;               // block: camera-relative corner x0, y0 (m), side (m), level

out vec3 v_rel;                // camera-relative displaced position (m)
out vec2 v_rest;               // camera-relative rest point (m): where the detail maps are anchored
out vec3 v_normal;
out float v_jacobian;
out float v_lost_var;
out float v_lost_jvar;
out float v_depth;
out float v_breaking;
out vec3 v_foam;               // foam mean cover, freshness, crest (foam.glsl foam_vertex)
out vec3 v_air_t;               // aerial perspective as L -> L * v_air_t + v_air_s, per vertex
out vec3 v_air_s;

const float EARTH_RADIUS = 6.371e6;

void main() {
    int level = int(in_node.w + 0.5);
    float cell = in_node.z / u_patch_quads;
    vec2 p = in_node.xy + in_grid * cell;
    // Geomorph (CDLOD): odd vertices slide onto the coarser grid over the outer part of the range.
    float d = length(vec3(p, u_cam_height));
    vec2 m = u_morph[level];
    float morph = clamp((d - m.x) / (m.y - m.x), 0.0, 1.0);
    vec2 odd = fract(in_grid * 0.5) * 2.0;
    p = in_node.xy + (in_grid - odd * morph) * cell;
    SeaSample s = sea_displace(p, cell * (1.0 + morph));
    // Earth's curvature: the sea drops r^2 / (R + sqrt(R^2 - r^2)) at horizontal distance r (no
    // cancellation), and its vertical tilts by r / R.
    float r2 = dot(s.pos.xy, s.pos.xy);
    float drop = r2 / (EARTH_RADIUS + sqrt(max(EARTH_RADIUS * EARTH_RADIUS - r2, 0.0)));
    v_rel = vec3(s.pos.xy, u_level_z + s.pos.z - drop);
#ifdef WATER_FIELD
    v_rel.z += land_height(p);  // the dry land behind a slope beach (water/land.py): 0 elsewhere
#endif
    v_rest = p;
    v_normal = normalize(s.normal + vec3(s.pos.xy / EARTH_RADIUS, 0.0) * s.normal.z);
    v_jacobian = s.jacobian;
    v_lost_var = s.lost_var;
    v_lost_jvar = s.lost_jvar;
    v_depth = s.depth;
    v_breaking = s.breaking;
#ifdef WATER_FIELD
    // only the shore draws it (water.frag.glsl); 2 m: triangles of 100 m on the 2 % beach
    v_swash = s.depth < 2.0 ? swash_vertex(p) : vec4(0.0);
#endif
#if WATER_FOAM
    v_foam = foam_vertex(s.jacobian, s.jacobian_past, s.lost_jvar, s.breaking, s.pos.z);
#else
    v_foam = vec3(0.0, 1.0, 0.0);
#endif
    // Aerial perspective is affine in the radiance and smooth in distance: the per-frame table of the
    // shared function over the sea (sea_tables.glsl) per vertex, interpolated per pixel.
    sea_aerial_perspective(v_rel, v_air_t, v_air_s);
    gl_Position = u_view_proj * vec4(v_rel, 1.0);
}
