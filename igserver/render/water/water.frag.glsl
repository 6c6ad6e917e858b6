// Sea surface shading (docs/design.md#water): sky reflection through Schlick's Fresnel (R0 = 0.02037), sun
// and moon glitter and local lights through the project's GGX lobe, detail slopes from the summed
// normal maps, depth-dependent colour in the shallows, foam where the surface is compressed, aerial
// perspective; no water inside hulls.
#include "generated/bindings.glsl"
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "water/sea_tables.glsl"
#include "water/detail_filter.glsl"
#ifdef WATER_UNDERWATER
#include "water/underwater.glsl"
#endif
#include "common/fog_relief.glsl"
#include "water/foam.glsl"
#include "water/foam_streaks.glsl"
#ifdef WATER_FIELD
#include "water/shore.glsl"
#endif

#ifndef MAX_HULLS
#define MAX_HULLS 32
#endif
uniform int u_hull_count;
uniform mat4 u_hull_inv[MAX_HULLS];   // camera-relative world -> hull box [-1, 1]^3

uniform sampler2D u_detail0;
uniform sampler2D u_detail1;
uniform sampler2D u_detail2;
uniform vec3 u_detail_map[3];         // per map: 1 / L (1/m), offset (cam xy mod L) / L
#if WATER_DETAIL_MAPS < 3
uniform vec4 u_detail_mean[3 - WATER_DETAIL_MAPS];  // the maps not read: their tile average (water.py)
#endif
uniform vec3 u_glint_dir;             // unit, toward the sun or the moon, whichever is brighter
uniform vec3 u_glint_illuminance;     // lux per channel of that light
uniform float u_min_slope_var;        // floor of the unresolved slope variance (glassy sea)

in vec3 v_rel;
in vec2 v_rest;
in vec3 v_normal;
in float v_jacobian;
in float v_lost_var;
in float v_lost_jvar;
in float v_depth;
in float v_breaking;
in vec3 v_foam;
#ifdef WATER_FIELD
in vec4 v_swash;                  // shore.glsl swash_vertex
#endif
in vec3 v_air_t;
in vec3 v_air_s;

layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

const float WATER_R0 = 0.02037;                    // Fresnel reflectance air-water, normal incidence
const vec3 ABSORPTION = vec3(0.35, 0.07, 0.045);    // 1/m, coastal water (red first)
const vec3 BOTTOM_ALBEDO = vec3(0.35, 0.30, 0.22);  // sand

// One detail map (1 / L, offset: u_detail_map) at the rest point; ``rest_dx``, ``rest_dy``: the rest
// point's screen derivatives, ``footprint``: the pixel's on the rest plane (m; detail_filter.glsl).
vec4 detail(sampler2D tex, vec3 map, vec2 rest_dx, vec2 rest_dy, float footprint) {
    vec2 uv = v_rest * map.x + map.yz;
#if WATER_DETAIL_FADE  // the mean slope faded by the pixel's footprint (water/detail_filter.glsl)
#if !WATER_DETAIL_MOTION  // a still eye (water.py compiles the motion's variant only for a moving one:
                          // llvmpipe runs both sides of a branch, even on a uniform)
    vec4 d = texture(tex, uv);
#else
    // blurred over the eye's motion: the sampler's footprint grown to it (footprint: main's, grown),
    // the fade with it
    float grow = footprint / max(rest_footprint(rest_dx, rest_dy), 1e-12);
    vec4 d = textureGrad(tex, uv, rest_dx * (map.x * grow), rest_dy * (map.x * grow));
#endif
    return vec4(d.xy * detail_fade_of(footprint * map.x), d.zw);
#else
    return texture(tex, uv);
#endif
}

// GGX specular of the water for a light of illuminance e from direction l.
vec3 glint(vec3 e, vec3 n, vec3 v, vec3 l, float alpha) {
    float n_dot_l = dot(n, l);
    if (n_dot_l <= 0.0) return vec3(0.0);
    vec3 h = normalize(v + l);
    float n_dot_v = max(dot(n, v), 1e-4);
    vec3 f = fresnel_schlick(max(dot(v, h), 0.0), vec3(WATER_R0));
    return e * f * ggx_distribution(n, h, max(dot(n, h), 0.0), alpha) * smith_visibility(n_dot_v, n_dot_l, alpha) * n_dot_l;
}

#ifdef WATER_FIELD
// The land behind a slope beach (water/land.py): the sand's colour (``sand``: dry or wet, lit by the
// level downwelling) turned to the profile's slope, mottled, and dune grass from the dune's rise on
// in patches. The mottle is the project's noise (two octaves, sigma 0.405) as the foam's table holds
// it (foam_streaks.glsl foam_z: z of unit variance, one lookup instead of two octaves of simplex
// noise), in world-fixed cells of LAND_CELL m, faded where a pixel spans a cell.
const vec3 DUNE_GRASS_ALBEDO = vec3(0.09, 0.12, 0.055); // marram grass, grey-green (leaves: R 0.05-0.1, G 0.1-0.15)
const float LAND_CELL = 7.8125;                         // m; LAND_PERIOD / LAND_CELL: 128 cells, twice the table's 64
vec3 land_colour(vec3 sand, vec3 e_local) {
    vec2 sy = land_coordinates(v_rest);
    vec3 prof = land_profile(max(sy.x, 0.0), sy.y);
    vec3 n = normalize(vec3(-(prof.y * u_shore_plane.xy + prof.z * u_swash_along.xy), 1.0));
    // the slope's irradiance over a level surface's: the sun and the moon by n.l, the part of the sky
    // dome the facet sees; local lights as on the level
    vec3 e_level = u_sun_illuminance * max(u_sun_dir.z, 0.0) + u_moon_illuminance * max(u_moon_dir.z, 0.0)
                 + PI * u_sky_ambient + e_local;
    vec3 e_slope = u_sun_illuminance * max(dot(n, u_sun_dir), 0.0) + u_moon_illuminance * max(dot(n, u_moon_dir), 0.0)
                 + PI * u_sky_ambient * (0.5 + 0.5 * n.z) + e_local;
    float fade = 1.0 - smoothstep(0.25, 1.0, fwidth(sy.x) / LAND_CELL);
    float mottle = fade * 0.405 * foam_z(sy / LAND_CELL);
    float grass = smoothstep(0.2, 0.9, dune_rise(sy.x, sy.y)) * clamp(0.8 + 0.5 * mottle, 0.0, 1.0);
    vec3 albedo = mix(vec3(1.0 + 0.08 * mottle), DUNE_GRASS_ALBEDO / BOTTOM_ALBEDO, grass);
    return sand * albedo * e_slope / max(e_level, vec3(1e-9));
}
#endif

void main() {
#ifdef WATER_HULLS  // only when hulls float in the sea: discard would disable early depth tests
    for (int i = 0; i < u_hull_count; ++i) {
        vec3 b = (u_hull_inv[i] * vec4(v_rel, 1.0)).xyz;
        if (all(lessThan(abs(b), vec3(1.0)))) discard;  // inside a hull: the sea stays out
    }
#endif
    // Mesh slope + detail slopes (3 summed maps), and what none of them resolves as roughness.
    // Only the first WATER_DETAIL_MAPS maps are read (a prefix, coarse tiles first); each other one is
    // either empty (the spectrum's detail band ends above it: mean 0) or fully minified on this block
    // (the sampler would return its 1x1 mip level): its tile average, u_detail_mean.
    // the rest point's screen derivatives, once for the detail maps and the foam (each reads the rest
    // point scaled), and the pixel's footprint on the rest plane, grown to a moving eye's motion
    vec2 rest_dx = dFdx(v_rest), rest_dy = dFdy(v_rest);
    float footprint = rest_footprint(rest_dx, rest_dy);
#if WATER_DETAIL_MOTION
    footprint = max(footprint, length(u_detail_motion));
#endif
#if WATER_DETAIL_MAPS > 0
    vec4 d0 = detail(u_detail0, u_detail_map[0], rest_dx, rest_dy, footprint);
#else
    vec4 d0 = u_detail_mean[0];
#endif
#if WATER_DETAIL_MAPS > 1
    vec4 d1 = detail(u_detail1, u_detail_map[1], rest_dx, rest_dy, footprint);
#else
    vec4 d1 = u_detail_mean[1 - WATER_DETAIL_MAPS];
#endif
#if WATER_DETAIL_MAPS > 2
    vec4 d2 = detail(u_detail2, u_detail_map[2], rest_dx, rest_dy, footprint);
#else
    vec4 d2 = u_detail_mean[2 - WATER_DETAIL_MAPS];
#endif
    vec2 slope = -v_normal.xy / max(v_normal.z, 0.05) + d0.xy + d1.xy + d2.xy;
    vec2 var2 = (d0.zw - d0.xy * d0.xy) + (d1.zw - d1.xy * d1.xy) + (d2.zw - d2.xy * d2.xy);
    float mss = max(var2.x + var2.y, 0.0) + v_lost_var + u_min_slope_var;
    float alpha = clamp(sqrt(mss), 0.02, 0.6);
    vec3 n = normalize(vec3(-slope, 1.0));
    float dist = length(v_rel);
    vec3 v = -v_rel / dist;
#ifdef WATER_UNDERWATER  // the camera is below the surface (water/underwater.glsl)
    out_color = vec4(pre_expose(underwater_mesh(n, v_normal, -v, dist, alpha, u_glint_dir, u_glint_illuminance)), 1.0);
    out_distance = dist;
    return;
#endif
    float n_dot_v = dot(n, v);
    if (n_dot_v < 0.02) {  // facet turned away by the detail maps: bend it back toward the eye
        n = normalize(n + v * (0.02 - n_dot_v));
        n_dot_v = 0.02;
    }
    // Sky reflection (the atmosphere's own radiance from the per-frame table; rays that would enter
    // the sea are mirrored up).
    vec3 r = reflect(-v, n);
    r.z = abs(r.z);
    float fresnel = fresnel_schlick(n_dot_v, vec3(WATER_R0)).x;
    vec3 sky = sky_reflection(r);
    // Direct light: sun and moon glitter, local lights (fires, lamps, spots) shimmering on the waves.
    // The brighter of the sun and the moon (water.py picks it: by day the moon's glitter is a
    // millionth of the sun's, by night the sun's direct light is zero).
    vec3 direct = glint(u_glint_illuminance, n, v, u_glint_dir, alpha);
    vec3 e_local = vec3(0.0);  // local-light irradiance on a horizontal surface (lux), for body/foam
#if LOCAL_LIGHTS
#if LIGHT_TILES  // the tile's lights only (common/lights.glsl)
    for (uvec2 lights = tile_lights(v_rel); any_light(lights);) {
        int i = next_light(lights);
#else
    for (int i = 0; i < u_light_count; ++i) {
#endif
        vec3 l;
        vec3 e = light_illuminance(i, v_rel, l);  // the shared light loop's falloff and spot cone
        direct += glint(e, n, v, l, alpha);
        e_local += e * max(l.z, 0.0);
    }
#endif
    // Light entering the water (lux on the surface) and coming back up: deep backscatter, or the
    // sand bottom seen through depth h along the down-and-up path (Beer-Lambert), in the shallows.
    vec3 e_down = sea_downwelling() + e_local;
#ifdef WATER_FIELD
    float cos_t = sqrt(1.0 - (1.0 - n_dot_v * n_dot_v) / (1.333 * 1.333));  // refracted ray
    vec3 through = exp(-ABSORPTION * max(v_depth, 0.0) * (1.0 + 1.0 / cos_t));
    vec3 body = (DEEP_ALBEDO * (1.0 - through) + BOTTOM_ALBEDO * through) * e_down / PI;
#else  // no bathymetry field: deep water everywhere (v_depth 1e4: nothing shows through, no surf, no beach)
    vec3 body = DEEP_ALBEDO * e_down / PI;
#endif
    vec3 lit = fresnel * sky + direct + (1.0 - fresnel) * body;
    // Whitecaps where the Gerstner surface pinches (J small) now or a few seconds ago (fresh white,
    // older grey-green and thinner), torn into streaks by the wind (foam.glsl); spindrift off crests.
#if WATER_FOAM
    float spray;
    float fresh = clamp(v_foam.y, 0.0, 1.0);
    float sparse = 1.0 - smoothstep(0.1, 0.7, v_breaking);  // the surf's foam lies in lines (foam.glsl foam_vertex)
    float foam = foam_cover(v_foam.x, fresh, v_rest, rest_dx, rest_dy, sparse, spray) * mix(FOAM_OLD, 1.0, fresh);
    spray *= u_spray.x * v_foam.z;
#else  // a sea too calm for whitecaps (foam.py foam_drawn)
    float foam = 0.0, spray = 0.0;
#endif
    // Foam is a rough white surface on the facet n: the sun and the moon by n.l, the sky by the part
    // of the dome the facet sees ((1 + n_z) / 2), local lights as on a level surface — so the foam on a
    // crest facing the sun is brighter than on its lee (a level downwelling value drew a flat sheet).
    vec3 e_foam = u_sun_illuminance * max(dot(n, u_sun_dir), 0.0) + u_moon_illuminance * max(dot(n, u_moon_dir), 0.0)
                + PI * u_sky_ambient * (0.5 + 0.5 * n.z) + e_local;
    lit = mix(lit, FOAM_FRESH * e_foam / PI, foam);
    lit = mix(lit, FOAM_FRESH * e_foam / PI, spray);  // spray: a white veil over whatever is below
    // Dry land of the bathymetry (h <= 0): the bare beach at the water level (there is no terrain
    // pipeline yet), under the swash that runs up it and back with each wave (shore.glsl), its front
    // white, the sand it wets darker (wet sand reflects about 60 % of dry sand's light).
#if defined(WATER_FIELD) && WATER_LAND  // a block reaching above the water (shore.py blocks_reaching_land)
    float land = shore_elevation(v_rest, v_depth);
    float land_step = fwidth(land);
    vec3 sw = vec3(0.0);  // the sea: no swash to draw
    if (land > -0.05) sw = swash(v_swash, land, land_step);
    float water = max(smoothstep(0.0, 0.05, -land), sw.x);
    vec3 sand = BOTTOM_ALBEDO * mix(1.0, 0.6, sw.z) * e_down / PI;  // Lambert
    if (u_land.w > 0.0 && land > -0.05) sand = land_colour(sand, e_local);
    lit = mix(mix(sand, lit, water), FOAM_FRESH * e_foam / PI, sw.y);
#endif
    // apply_aerial_perspective, per vertex; a fog top's relief per pixel (its cells span few vertices)
    out_color = vec4(pre_expose(lit * v_air_t + v_air_s * fog_top_relief(v_rel / dist)), 1.0);
    out_distance = dist;
}
