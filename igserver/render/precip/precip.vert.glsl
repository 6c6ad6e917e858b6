// Precipitation streaks (docs/design.md#precipitation): one screen-aligned quad per particle copy, from the particle's
// position T ago to its current position (particles.py), at least one pixel wide.
//
// Particle i (gl_VertexID / 4) of a tile sits at q_i + the tile's offset, camera-relative. One
// indirect command per level draws its tiles as instances (the tile's offset and level are the
// instance's attribute, from the command's base instance on). Its light comes from precip_light.comp.glsl (once per streak). Opacity carries
// the coverage of the m real drops one streak stands for: a drop of diameter D_px (pixels) sweeping
// the streak during the exposure covers D_px^2 pixel-exposures in all, however long the streak
// (time-averaged coverage of a moving disk), so spread over the quad's area w (l + w):
//     alpha = m D_px^2 / (w (l_px + w)),   w = max(D_px, 1 px).
// Where that would exceed 1 (m slow snowflakes on a short streak), the quad widens instead until
// w (l + w) = m D_px^2 at alpha 1, so the coverage is kept rather than clipped away - up to 4x its
// width (beyond, at extreme rates under the cost cap, opacity clips at 1 and coverage is lost). Streaks wider
// than 2 px are drawn as capsules (round flakes and drop ends), their opacity over the capsule's
// area w l + pi w^2 / 4.
// It fades out toward u_fade (beyond, the extinction in the visibility carries the rain) and near
// the camera (a drop centimetres from the lens is a defocused blur, not a streak).
#include "common/frame.glsl"
#include "precip/precip_common.glsl"

uniform float u_level_drops[MAX_LEVELS];  // m, drops per streak of each level
in vec4 in_tile;                   // per instance: xyz the tile's camera-relative offset (m), w its level
uniform float u_fade;              // m, streaks gone beyond
uniform float u_px_per_tan;        // px per unit tangent (0.5 height P[1][1])

out vec3 v_rel;
noperspective out vec2 v_local;  // px: along the quad from its tail end, across from the axis
flat out vec2 v_shape;     // px: streak length l, width w (capsule when w > 2)
flat out vec3 v_radiance;  // pre-exposed, after the aerial perspective
flat out float v_alpha;

// The quad's 4 corners; an index buffer makes its two triangles (0 1 2, 0 2 3), so each corner is
// shaded once (the draw's vertex cache) instead of 6 vertices per quad.
const vec2 CORNERS[4] = vec2[4](vec2(0, -1), vec2(1, -1), vec2(1, 1), vec2(0, 1));

void main() {
    int index = gl_VertexID / 4;
    int level = int(in_tile.w);
    ivec4 lv = u_levels[level];
    Particle particle = particles[lv.LEVEL_FIRST_PARTICLE + index];
    vec2 corner = CORNERS[gl_VertexID % 4];  // x: 0 = tail (T ago), 1 = head (now); y: side
    vec3 head = particle.pos_diameter.xyz + in_tile.xyz;
    vec3 tail = head - particle.streak_brightness.xyz;
    vec4 clip_tail = u_view_proj * vec4(tail, 1.0);
    vec4 clip_head = u_view_proj * vec4(head, 1.0);
    float dist = length(head);
    v_alpha = 0.0;
    v_radiance = vec3(0.0);
    v_local = vec2(0.0);
    v_shape = vec2(0.0);
    v_rel = head;
    if (clip_tail.w < 0.05 || clip_head.w < 0.05 || dist > u_fade) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // behind the camera or out of range: culled
        return;
    }
    vec2 s_tail = (clip_tail.xy / clip_tail.w * 0.5 + 0.5) * u_resolution;
    vec2 s_head = (clip_head.xy / clip_head.w * 0.5 + 0.5) * u_resolution;
    vec2 d = s_head - s_tail;
    float l_px = length(d);
    vec2 along = l_px > 1e-3 ? d / l_px : vec2(0.0, 1.0);
    vec2 across = vec2(-along.y, along.x);
    float d_px = particle.pos_diameter.w / dist * u_px_per_tan;
    float w = max(d_px, 1.0);
    float area = u_level_drops[level] * d_px * d_px;  // px^2 of coverage this streak carries
    // Widened at most 4x (16x the flake's area): fill cost stays bounded when the cap makes m huge.
    if (area > w * (l_px + w)) w = min(0.5 * (sqrt(l_px * l_px + 4.0 * area) - l_px), 4.0 * w);
    vec2 s = mix(s_tail, s_head, corner.x) + along * (corner.x * 2.0 - 1.0) * 0.5 * w + across * corner.y * 0.5 * w;
    vec4 clip = mix(clip_tail, clip_head, corner.x);
    gl_Position = vec4((s / u_resolution * 2.0 - 1.0) * clip.w, clip.z, clip.w);
    v_rel = mix(tail, head, corner.x);
    v_local = vec2(corner.x * (l_px + w), corner.y * 0.5 * w);
    v_shape = vec2(l_px, w);

    float coverage = area / (w > 2.0 ? w * l_px + 0.25 * PI * w * w : w * (l_px + w));
    float fade = (1.0 - smoothstep(0.6 * u_fade, u_fade, dist)) * smoothstep(0.2, 0.8, dist);
    v_alpha = clamp(coverage, 0.0, 1.0) * fade;
    v_radiance = radiance[lv.LEVEL_FIRST_STREAK + gl_InstanceID * lv.LEVEL_PARTICLES + index].rgb;
}
