// The detail maps' first pass (detail_synth.py): each wave's phasor e^{iφ}, φ = φ0 − ω t, into the
// first places of detail_grid (detail_synth.glsl), read by the bins of every level.
#include "water/detail_synth.glsl"

layout(local_size_x = DETAIL_GROUP) in;

uniform int u_waves;  // waves of the maps written (a prefix: the first maps')

void main() {
    int id = int(gl_GlobalInvocationID.x);
    if (id >= u_waves) return;
    float phi = detail_angle(detail_phase(id));
    detail_grid[id] = vec2(cos(phi), sin(phi));
}
