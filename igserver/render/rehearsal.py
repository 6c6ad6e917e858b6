"""Compiling ahead the programs a stream will need when its scene changes: a rehearsal.

A GL driver turns a program into machine code the first time it is drawn with, and a compile is
long next to a frame: many frames' time with a warm shader cache, over a second of LLVM work on
llvmpipe with a cold one (docs/operations.md has the figures). A simulator's host starts a fire or
the rain whenever its exercise says so, and a picture frozen that long is what a trainee sees. So
the IG compiles what a scene may come to need before it is asked to show it.

The programs are variants chosen by ``#define``: what a frame draws (volumes of each effect kind,
rain or snow, the underwater passes), whether local lights are compiled in (``LOCAL_LIGHTS``,
``SPOT_LIGHTS``) and looped per screen tile (``LIGHT_TILES``), the fog halos' count (``HALO_COUNT``) and the sea's foam (none in a calm, wind
rows in a rough sea). Which variants a scene will meet cannot be listed without
drawing it, since the passes decide them from the frame, so the rehearsal draws: the stream's scene
with the changes a host most often makes (``rehearsals``), at the scene's own size, into the
stream's own targets, and waits for each to finish (llvmpipe compiles while it rasterises). The
stream's state - its exposure adaptation, eased fog, meter cells, overload controller, frame count -
is put back afterwards, and no frame is read or returned: what the host sees next is as if the
rehearsal had not happened, except that its first fire costs a frame, not a compile.
"""

from __future__ import annotations

import time

from ..effect_kinds import EFFECT_KINDS
from ..scene.model import MAX_EFFECTS, PRESET_NAMES, Effect, Light, Scene
from .camera import make_view
from .frame import FrameState
from .frame_block import MAX_LIGHTS
from .multiview import release_view_state, swap_view_state
from .operating_points import SCALES
from .overload import FrameQuality

# Where the rehearsal's effects and lights stand: this far ahead of the camera (m), a little
# below its eye, so that every pass that would draw them does (in the frustum, not fogged out).
AHEAD_M = 25.0
BELOW_EYE_M = 1.5
# The winds a sea is rehearsed at (m/s): its programs follow its state, in steps no single wind shows
# all of. A glassy calm (2: no foam, the fewest detail maps resolved), light airs whose ripples a
# block already resolves in more maps (3), the foam's first dots and streaks (4), a fresh breeze's
# foam without a second streak octave (10) and a storm's, with every detail map (28). Together
# they meet every variant a sweep from 0.5 to 32 m/s meets in the example sea scenes.
SEA_WINDS = (2.0, 3.0, 4.0, 10.0, 28.0)
UNDER_M = 3.0  # m below the mean water level: the eye under the surface
# A lamp lighting a patch of the view only: 6 m of reach, 30 m ahead and 10 m aside.
LAMP_AHEAD_M, LAMP_RIGHT_M, LAMP_RANGE_M = 30.0, 10.0, 6.0


def _ahead(scene: Scene, forward_m: float, right_m: float = 0.0) -> tuple[float, float, float]:
    view = make_view(scene.camera)
    p = view.position + forward_m * view.forward + right_m * view.rotation[:, 0]
    return (float(p[0]), float(p[1]), float(p[2] - BELOW_EYE_M))


def rehearsals(scene: Scene) -> list[Scene]:
    """The scenes drawn to compile ahead: ``scene`` with one more fire (smoking: its plume too);
    with one more effect of every kind, a point and a spot light and the rain; with a lamp, and a lamp
    and a spot, that light a patch of the view; with one more fire and the snow; in a scene without
    local lights, with the rain alone; in a scene with a sea, with each of ``SEA_WINDS`` and with the
    eye under the surface. Lights and effects are added only while the renderer's limits leave room."""
    base = scene.model_copy(update={
        "channels": [],  # every channel draws with the same programs: the camera's view compiles them
        "quality": scene.quality.model_copy(update={"target_fps": 0.0}),
    })
    room_effects = MAX_EFFECTS - len(scene.effects)
    room_lights = MAX_LIGHTS - len(scene.lights) - len(scene.effects) - len(EFFECT_KINDS)

    def effect(i: int, kind: str) -> Effect:
        return Effect(id=f"rehearsal-{kind}-{i}", type=kind, position=_ahead(scene, AHEAD_M, 4.0 * i),
                      diameter=2.0, fade=0.0, emits_smoke=kind == "fire")

    def weather(kind: str):
        fall = scene.weather.precipitation.model_copy(update={"type": kind, "rate": 4.0})
        return scene.weather.model_copy(update={"precipitation": fall})

    out = []
    if room_effects >= 1:
        out.append(base.model_copy(update={"effects": [*scene.effects, effect(0, "fire")]}))
    kinds = list(EFFECT_KINDS)[: max(room_effects, 0)]
    lights = [Light(id="rehearsal-point", position=_ahead(scene, 10.0, -3.0), range=40.0),
              Light(id="rehearsal-spot", type="spot", position=_ahead(scene, 10.0, 3.0), range=40.0,
                    heading=scene.camera.heading, pitch=-30.0)] if room_lights >= 2 else []
    out.append(base.model_copy(update={"effects": [*scene.effects, *(effect(i, k) for i, k in enumerate(kinds))],
                                       "lights": [*scene.lights, *lights], "weather": weather("rain")}))
    if room_lights >= 2:
        # Lamps whose reach covers part of the view: a pixel then loops over its screen tile's lights
        # (light_tiles.py, LIGHT_TILES), with and without a spot among them. The fire's and the lights'
        # above reach the whole view, which keeps the plain loop.
        lamp = Light(id="rehearsal-lamp", position=_ahead(scene, LAMP_AHEAD_M, LAMP_RIGHT_M), range=LAMP_RANGE_M)
        spot = Light(id="rehearsal-lamp-spot", type="spot", position=_ahead(scene, LAMP_AHEAD_M, -LAMP_RIGHT_M),
                     range=LAMP_RANGE_M, heading=scene.camera.heading, pitch=-30.0)
        out.append(base.model_copy(update={"lights": [*scene.lights, lamp]}))
        out.append(base.model_copy(update={"lights": [*scene.lights, lamp, spot]}))
    if room_effects >= 1:
        out.append(base.model_copy(update={"effects": [*scene.effects, effect(0, "fire")], "weather": weather("snow")}))
    if not scene.lights and not any(EFFECT_KINDS[e.type].casts_light for e in scene.effects):
        out.append(base.model_copy(update={"weather": weather("rain")}))  # the rain unlit by local lights
    if scene.ocean.enabled:
        # The sea's programs follow its state (SEA_WINDS), and the eye under the surface draws the
        # underwater passes.
        for wind in SEA_WINDS:
            out.append(base.model_copy(update={
                "weather": scene.weather.model_copy(update={"wind_speed": wind}),
                "ocean": scene.ocean.model_copy(update={"sea_state": None, "fetch_km": None, "duration_h": None})}))
        x, y, _ = scene.camera.position
        out.append(base.model_copy(update={"camera": scene.camera.model_copy(
            update={"position": (x, y, scene.ocean.level - UNDER_M)})}))
    return out


def rehearse(renderer, scene: Scene, report=None) -> dict:
    """Draw ``rehearsal_draws(scene)`` on ``renderer`` and put its stream's state back; ``report(done,
    total)`` after each scene drawn (the render process's progress messages: a long rehearsal is alive).
    Returns what it did: {"scenes": drawn, "programs": compiled by them, "seconds": wall time}."""
    t0 = time.perf_counter()
    compiled = len(renderer.programs)
    # The stream's state, set aside: what the frames carry from one to the next (adaptation, fog,
    # meter, controller, count, scale), the passes' per-view state (multiview.swap_view_state: a
    # fresh view's for the rehearsal, released after it), the targets and the channels'. The
    # rehearsal draws into targets of its own, released after it.
    kept = {name: getattr(renderer, name) for name in STREAM_STATE}
    channels = {name: getattr(renderer, name) for name in CHANNEL_STATE}
    for name in CHANNEL_STATE:  # the rehearsal draws no channels: theirs are not "gone" for it
        setattr(renderer, name, {})
    renderer._targets = renderer._upscaler = None  # its own (a scaled draw would replace the stream's)
    held = swap_view_state(renderer.ctx, renderer.graph.passes, {})
    draws = rehearsal_draws(scene)
    try:
        for drawn, (scale, rehearsal) in enumerate(draws, 1):
            renderer.render_scale = scale
            renderer.frame_state, renderer.frame_quality = FrameState(), FrameQuality()
            renderer._draw(rehearsal, timed=False)
            renderer.ctx.finish()
            if report is not None:
                report(drawn, len(draws))
    finally:
        release_view_state(swap_view_state(renderer.ctx, renderer.graph.passes, held))
        for made in (renderer._targets, renderer._upscaler):
            if made is not None:
                made.release()
        for name, value in {**kept, **channels}.items():
            setattr(renderer, name, value)
    return {"scenes": len(draws), "programs": len(renderer.programs) - compiled,
            "seconds": time.perf_counter() - t0}


def rehearsal_draws(scene: Scene) -> list[tuple[float, Scene]]:
    """(internal render scale, scene) of each draw: ``rehearsals(scene)`` at the full size; for a
    scene that holds a frame rate, whose controller may draw it smaller and at any rung of the
    presets' ladder (render/overload.py), those again at the smallest scale, and the scene itself at
    every scale with each preset. The programs follow the frame's pixel count (a frame of fewer
    pixels than the aerial-perspective table has nodes compiles the exact variants, the post pass
    downsamples in other steps) and the knobs (the sea's detail-map resolution, the volumes'), so a
    controller that steps down under load does not meet a compile, the worst moment for one."""
    changes = rehearsals(scene)
    if scene.quality.target_fps <= 0:
        return [(1.0, s) for s in changes]
    still = scene.model_copy(update={"channels": []})
    presets = [still.model_copy(update={"quality": still.quality.model_copy(update={"preset": p, "target_fps": 0.0})})
               for p in PRESET_NAMES if p != "auto"]
    return ([(scale, s) for scale in (1.0, min(SCALES)) for s in changes]
            + [(scale, s) for scale in SCALES for s in presets])


# The renderer's attributes a rehearsal puts back (render/renderer.py).
STREAM_STATE = ("frame_state", "frame_quality", "frames_rendered", "_targets", "_upscaler", "render_scale")
CHANNEL_STATE = ("_channel_targets", "channel_meters", "channel_meter_copies", "view_states", "_channel_upscalers")
