// Reduced-resolution march, step 1: the scene distance of each low-resolution pixel = the NEAREST
// of the SCALE x SCALE full-resolution pixels it covers (common/nearest_distance.glsl). A
// volume marched to the nearest surface is never drawn over it; the full-resolution pixels further
// away are filled by the depth-aware upsampling from neighbours whose distance matches theirs
// (upsample.frag.glsl).
#include "common/nearest_distance.glsl"
uniform sampler2D u_scene_distance;  // m, full resolution, 1e30 = sky
// SCALE: the march's reduction, compiled in (volumes.py: one variant per scale, 2 or 4)
layout(location = 0) out float out_distance;
void main() {
    out_distance = nearest_distance(u_scene_distance, ivec2(gl_FragCoord.xy), SCALE);
}
