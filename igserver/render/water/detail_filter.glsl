// The detail maps' footprint filter (water.frag.glsl detail()): each map's mean slope fades out where
// a pixel spans too much of the map's longest wave, and what fades goes to the roughness — the map's
// second moments are kept, so the variance the shader derives, E[s^2] - (w E[s])^2, grows by what the
// slope lost (variance to roughness; LEAN mapping). A map's tile is DETAIL_MIN_CYCLES of its longest
// wave (detail.py) and its band spans a wavelength ratio of 7.7: the fade starts where that wave is
// 16 pixels long (the band's middle wave, 2.8 times shorter, ~6 pixels) and is complete at 8 (the
// middle wave at 3 pixels, the shortest at 1). Without it a tile of a dozen waves at snapped
// directions drew a diamond lattice over the near water seen level from 2 m, each frame a different
// one for a moving camera (the waves shift by most of a period between frames at 5 m/s).
const float DETAIL_LONGEST_CYCLES = 5.0;        // detail.py DETAIL_MIN_CYCLES
const vec2 DETAIL_FADE_PX = vec2(8.0, 16.0);     // longest wave's length (px): gone, whole

// The fade for a footprint of ``footprint`` tile widths (the longer axis).
float detail_fade_of(float footprint) {
    float period_px = 1.0 / (DETAIL_LONGEST_CYCLES * max(footprint, 1e-9));
    return smoothstep(DETAIL_FADE_PX.x, DETAIL_FADE_PX.y, period_px);
}

// Motion: a moving eye passes a ripple by more than half its length between frames at a few m/s
// (0.17 m a frame at 5 m/s and 30 frames/s; the finer map's waves are 4-40 cm), and each frame then
// shows it at an unrelated phase: shimmer. The maps are blurred over the eye's displacement across
// the frame (water.py detail_motion; a full-interval shutter: a wave as long as the displacement
// averages out, one twice as long keeps 64 % of its amplitude): the footprint grows to the
// displacement wherever that is longer, and the fade and the roughness follow it as for a far pixel.
uniform vec2 u_detail_motion;  // m (world x, y): the eye's displacement since the previous frame; 0: still

// The pixel's footprint on the sea's rest plane (m, the longer axis) from the rest point's screen
// derivatives dx, dy. Every map reads the rest point over its tile side L, so its footprint in tile
// widths is this over L: one footprint serves the three maps.
float rest_footprint(vec2 dx, vec2 dy) { return sqrt(max(dot(dx, dx), dot(dy, dy))); }
