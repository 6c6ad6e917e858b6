"""Rendered frames show what CIGI packets set: Celestial Sphere Control noon vs midnight, Atmosphere
Control visibility 300 m, a fire started by Component Control (tiny frames, the session's renderer)."""

from __future__ import annotations

import numpy as np

from helpers import luminance, tiny
from igserver.cigi.datagram import build
from igserver.cigi.engine import CigiEngine
from igserver.cigi.packets_host import (AtmosphereControl, CelestialSphereControl, ComponentControl, EntityControl,
                                        IGControl, ViewControl, ViewDefinition)
from igserver.protocol.metrics import ServiceMetrics
from igserver.protocol.state import StateStore

LAT0, LON0 = 59.93, 30.31
M_PER_DEG_LAT = 111_412.0
FIXED_EXPOSURE = {"camera": {"exposure_ev": 12.0, "width": 64, "height": 36}}


def cigi_scene(*packets, base: dict | None = None, seconds: float = 10.0):
    """The scene after a host message of ``packets`` at sim_time 10 s, then an empty one ``seconds`` later
    (synchronous mode: the host's timestamps are the clock; a fade started by the first has run by then)."""
    engine = CigiEngine(StateStore(tiny(base)), ServiceMetrics())
    assert engine.handle(build([IGControl(host_frame=1, timestamp=1_000_000, timestamp_valid=True), *packets]))
    later = int((10.0 + seconds) * 100_000)
    assert engine.handle(build([IGControl(host_frame=2, timestamp=later, timestamp_valid=True)]))
    return engine.store.scene


def ownship_view(target_north: float, **view):
    """The ownship at the origin heading north with the eyepoint on it, 3 m up, and a 4 m box ahead."""
    return [EntityControl(entity_id=1, entity_type=0, lat=LAT0, lon=LON0, alt=0.0),
            ViewControl(entity_id=1, z=-3.0, **view),
            EntityControl(entity_id=2, entity_type=0, lat=LAT0 + target_north / M_PER_DEG_LAT, lon=LON0, alt=0.0)]


def test_celestial_noon_brighter_than_midnight(renderer):
    # 21 March at 59.93 N 30.31 E: the sun culminates ~10:00 UTC at ~30 deg and is ~30 deg down at 22:00
    noon = cigi_scene(CelestialSphereControl(hour=10, minute=0, date=3212026), *ownship_view(50.0, pitch=10.0),
                      base=FIXED_EXPOSURE)
    night = cigi_scene(CelestialSphereControl(hour=22, minute=0, date=3212026), *ownship_view(50.0, pitch=10.0),
                       base=FIXED_EXPOSURE)
    assert noon.time.utc.hour == 10 and night.time.utc.hour == 22
    bright, dark = (luminance(renderer.render(s).rgba).mean() for s in (noon, night))
    assert bright > 20.0 * max(dark, 0.5), (bright, dark)


def test_atmosphere_visibility_300_m_hides_a_box_at_400_m(renderer):
    # a 3-degree telephoto (View Definition) on a 2 m box 400 m ahead: its contrast is the picture with
    # the box minus the picture without it; Koschmieder: 300 m visibility leaves e^(-3.9 * 400/300) = 0.5 %
    lens = ViewDefinition(left=-1.5, right=1.5, top=0.85, bottom=-0.85)

    def contrast(visibility: float) -> float:
        common = [CelestialSphereControl(hour=10, date=3212026), AtmosphereControl(visibility=visibility), lens]
        view = ownship_view(400.0)
        with_box = cigi_scene(*common, *view)
        without = cigi_scene(*common, *view[:2])
        assert with_box.atmosphere.visibility == visibility and with_box.camera.frustum.right == 1.5
        a, b = (luminance(renderer.render(s).rgba) for s in (with_box, without))
        return float(np.abs(a - b).max() / max(b.mean(), 1.0))

    clear, foggy = contrast(30_000.0), contrast(300.0)
    assert clear > 0.1 and foggy < 0.2 * clear, (clear, foggy)


def test_component_control_starts_a_fire(renderer):
    def centre(state: int) -> float:
        packets = [CelestialSphereControl(hour=22, date=12212026), *ownship_view(30.0)]
        if state >= 0:
            packets.append(ComponentControl(component_id=1, instance_id=2, component_state=state,
                                            data2=0x40800000))  # a fire, 4 m across
        scene = cigi_scene(*packets, base={"camera": {"exposure_ev": 2.0}})
        if state == 1:
            assert scene.effects[0].active and scene.effects[0].type == "fire"
        image = luminance(renderer.render(scene).rgba)
        h, w = image.shape
        return float(image[h // 4:h // 2 + 2, w // 2 - 4:w // 2 + 4].mean())

    dark, burning = centre(-1), centre(1)
    assert burning > dark + 20.0, (dark, burning)
    stopped = centre(0)  # started stopped: after its fade there is nothing
    assert stopped < dark + 5.0, (dark, stopped)
