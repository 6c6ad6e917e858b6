"""CIGI host messages -> the one scene state: each honoured packet's fields, whole-datagram rejection,
arrival order with REST, synchronous mode, and the HAT/HOT and LOS answers."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from helpers import tiny
from igserver.cigi.codec import LITTLE
from igserver.cigi.datagram import build, parse_ig_message
from igserver.cigi.engine import CigiEngine
from igserver.cigi.geo import LocalFrame
from igserver.cigi.packets_host import (
    ArticulatedPartControl, AtmosphereControl, CelestialSphereControl, ComponentControl, EntityControl,
    EnvironmentalRegionControl, HatHotRequest, IGControl, LosSegmentRequest, LosVectorRequest,
    MaritimeSurfaceConditionsControl, RateControl, ShortArticulatedPartControl, ShortComponentControl,
    ViewControl, ViewDefinition, WaveControl, WeatherControl)
from igserver.cigi.packets_ig import HatHotExtendedResponse, HatHotResponse, LosResponse
from igserver.protocol.metrics import ServiceMetrics
from igserver.protocol.routers.query import water_height
from igserver.protocol.state import StateStore
from igserver.scene.files import load_scene

LAT0, LON0 = 59.93, 30.31


def f(value: float) -> int:
    """A float32 as a Component Control data word."""
    return struct.unpack("<I", struct.pack("<f", value))[0]


def engine(patch: dict | None = None, **kwargs) -> CigiEngine:
    store = StateStore(tiny(patch))
    return CigiEngine(store, ServiceMetrics(), load_scene=load_scene, **kwargs)


def send(e: CigiEngine, *packets, frame: int = 1, order: str = ">", **ig) -> bool:
    return e.handle(build([IGControl(host_frame=frame, **ig), *packets], order)) is not None


def ship(number=1, type_=1, north=0.0, **kwargs) -> EntityControl:
    return EntityControl(entity_id=number, entity_type=type_, lat=LAT0 + north / 111_412.0, lon=LON0, **kwargs)


def test_entity_create_move_attach_destroy():
    e = engine()
    assert send(e, ship(yaw=90.0), EntityControl(entity_id=2, entity_type=3, attach_state=True, parent_id=1,
                                                 lat=10.0, lon=0.0, alt=-2.0))
    scene = e.store.scene
    boat, crate = scene.entities
    assert (boat.id, boat.model, crate.model) == ("cigi.1", "patrol_boat", "crate")
    assert boat.heading == 90.0 and boat.position == pytest.approx(LocalFrame.of(scene.location).to_enu(LAT0, LON0, 0))
    # attached 10 m ahead (x forward), 2 m up (z down): the boat heads east, so the crate is 10 m east
    assert np.subtract(crate.position, boat.position) == pytest.approx([10.0, 0.0, 2.0], abs=1e-9)
    assert send(e, ship(north=100.0, yaw=0.0), frame=2)  # the parent moves and turns: the child follows
    boat, crate = e.store.scene.entities
    assert np.subtract(crate.position, boat.position) == pytest.approx([0.0, 10.0, 2.0], abs=1e-6)
    assert send(e, ComponentControl(component_id=1, instance_id=2, component_state=1), frame=3)
    assert [fx.id for fx in e.store.scene.effects] == ["cigi.2.fx1"]
    assert send(e, EntityControl(entity_id=1, entity_state=2), frame=4)  # destroyed with what hangs on it
    assert e.store.scene.entities == [] and e.store.scene.effects == []
    assert send(e, ship(entity_state=0), frame=5)
    assert e.store.scene.entities[0].visible is False


def test_components_start_stop_fade_and_lights():
    e = engine()
    send(e, ship(), ComponentControl(component_id=1, instance_id=1, component_state=1, data1=1, data2=f(4.0),
                                     data3=f(2.0), data4=f(6.0), data5=1))
    fx = e.store.scene.effects[0]
    assert (fx.type, fx.diameter, fx.intensity, fx.fade, fx.emits_smoke, fx.active) == ("smoke", 4.0, 2.0, 6.0,
                                                                                         True, True)
    assert fx.position == e.store.scene.entities[0].position
    send(e, ShortComponentControl(component_id=1, instance_id=1, component_state=0, data1=1), frame=2)
    fx = e.store.scene.effects[0]
    assert fx.active is False and fx.diameter == 4.0 and fx.changed_at is not None  # stopped: fades out
    send(e, ComponentControl(component_id=1, instance_id=1, component_state=2), frame=3)
    assert e.store.scene.effects == []
    send(e, ComponentControl(component_id=64, instance_id=1, component_state=1, data1=f(5000.0),
                             data2=0xFF0000, data3=f(50.0), data4=f(8.0)), frame=4)
    light = e.store.scene.lights[0]
    assert (light.intensity, light.color, light.range) == (5000.0, (1.0, 0.0, 0.0), 50.0)
    assert light.position[2] == pytest.approx(e.store.scene.entities[0].position[2] + 8.0)
    send(e, ShortComponentControl(component_id=64, instance_id=1, component_state=0), frame=5)
    assert e.store.scene.lights[0].intensity == 0.0
    send(e, ShortComponentControl(component_id=64, instance_id=1, component_state=1), frame=6)
    assert e.store.scene.lights[0].intensity == 5000.0  # on again at the intensity it had
    # another class: read, counted as skipped, nothing changes
    before = e.store.revision
    assert send(e, ComponentControl(component_class=13, component_id=5), frame=7)
    assert e.store.scene.lights[0].intensity == 5000.0 and e.store.revision == before + 1


def test_articulated_parts_and_view():
    e = engine()
    send(e, ship(yaw=0.0), ArticulatedPartControl(entity_id=1, part_id=1, yaw_enable=True, yaw=45.0,
                                                  z_enable=True, z=-0.5),
         ShortArticulatedPartControl(entity_id=1, part_id1=2, dof_select1=5, dof1=10.0),
         ViewControl(entity_id=1, x=-30.0, z=-10.0, pitch=-5.0),
         ViewDefinition(near=0.5, far=20_000.0, left=-40.0, right=40.0, top=25.0, bottom=-25.0))
    scene = e.store.scene
    parts = scene.entities[0].parts
    assert parts["radar"].heading == 45.0 and parts["radar"].offset == (0.0, 0.0, 0.5)
    assert parts["gun"].pitch == 10.0
    cam, boat = scene.camera, scene.entities[0]
    assert np.subtract(cam.position, boat.position) == pytest.approx([0.0, -30.0, 10.0], abs=1e-6)
    assert (cam.heading, cam.pitch) == pytest.approx((0.0, -5.0))
    assert (cam.near, cam.far, cam.frustum.left, cam.frustum.top) == pytest.approx((0.5, 20_000.0, -40.0, 25.0))
    send(e, ship(north=50.0, yaw=180.0), frame=2)  # the eyepoint rides along
    cam, boat = e.store.scene.camera, e.store.scene.entities[0]
    assert np.subtract(cam.position, boat.position) == pytest.approx([0.0, 30.0, 10.0], abs=1e-6)
    assert cam.heading == pytest.approx(180.0)


def test_environment():
    e = engine()
    send(e, CelestialSphereControl(hour=0, minute=30, date=12252026),
         AtmosphereControl(visibility=300.0, humidity=100, horizontal_wind=12.0, wind_direction=90.0),
         WeatherControl(layer_id=4, weather_enable=True, severity=3),
         WeatherControl(layer_id=1, cloud_type=5, coverage=40.0, base_elevation=9000.0),
         MaritimeSurfaceConditionsControl(surface_enable=True, sea_surface_height=1.5),
         WaveControl(wave_id=0, height=3.0), WaveControl(wave_id=1, height=2.0, period=12.0, direction=45.0))
    s = e.store.scene
    assert s.time.utc.isoformat() == "2026-12-25T00:30:00+00:00"
    assert (s.atmosphere.visibility, s.atmosphere.turbidity) == (300.0, 6.0)
    assert (s.weather.wind_speed, s.weather.wind_direction) == (12.0, 90.0)
    assert (s.weather.precipitation.type, s.weather.precipitation.rate) == ("rain", 12.0)
    assert (s.weather.cirrus_coverage, s.weather.cirrus_altitude) == (0.4, 9000.0)
    assert (s.ocean.enabled, s.ocean.level, s.ocean.sea_state) == (True, 1.5, 5)
    assert (s.ocean.swell.height, s.ocean.swell.period, s.ocean.swell.direction) == (2.0, 12.0, 45.0)
    send(e, WeatherControl(layer_id=0, weather_enable=True, base_elevation=0.0, thickness=80.0, visibility=150.0),
         WeatherControl(layer_id=4, weather_enable=False), frame=2)
    s = e.store.scene
    assert (s.atmosphere.fog_top, s.atmosphere.visibility, s.weather.precipitation.type) == (80.0, 150.0, "none")
    # regional weather and regions: kept, counted, not rendered
    send(e, EnvironmentalRegionControl(region_id=3, lat=LAT0, lon=LON0),
         WeatherControl(scope=1, region_id=3, layer_id=4, severity=5), frame=3)
    assert e.store.scene.weather.precipitation.type == "none" and 3 in e.session.regions
    assert e.counters.not_rendered._metric.labels(what="regional_weather")._value.get() == 1


def test_whole_datagram_rejected_and_counted():
    e = engine()
    send(e, ship())
    before, revision, session = e.store.scene, e.store.revision, e.session
    # a valid entity move, then a value the scene refuses (wind 200 m/s): nothing of it applies
    assert not send(e, ship(north=500.0), AtmosphereControl(horizontal_wind=200.0), frame=2)
    assert not send(e, ComponentControl(component_id=1, instance_id=9, component_state=1), frame=3)  # no entity 9
    assert not send(e, ship(north=10.0), ComponentControl(component_id=1, instance_id=1, component_state=1,
                                                            data2=0x7FC00000), frame=4)  # NaN diameter
    assert e.store.revision == revision and e.session is session
    assert e.store.scene.model_copy(update={"time": before.time}) == before  # only the clock ran on
    rejected = e.counters.rejected._metric
    assert [rejected.labels(kind=k)._value.get() for k in ("validation", "unknown_entity", "non_finite")] == [1, 1, 1]


def test_rest_and_cigi_apply_in_arrival_order():
    e = engine()
    send(e, AtmosphereControl(visibility=300.0))
    e.store.patch({"atmosphere": {"visibility": 1000.0}, "camera": {"fov_y": 40.0}})
    send(e, ship(), frame=2)  # CIGI does not send visibility here: the REST value stays
    assert (e.store.scene.atmosphere.visibility, e.store.scene.camera.fov_y) == (1000.0, 40.0)
    send(e, AtmosphereControl(visibility=500.0), frame=3)
    assert e.store.scene.atmosphere.visibility == 500.0


def test_reset_removes_what_cigi_made():
    e = engine({"entities": [{"id": "rest_box"}]})
    send(e, ship(), ComponentControl(component_id=1, instance_id=1, component_state=1))
    assert len(e.store.scene.entities) == 2
    send(e, ship(north=10.0), frame=2, ig_mode=0)  # reset/standby: the rest of the message is ignored
    assert [x.id for x in e.store.scene.entities] == ["rest_box"] and e.store.scene.effects == []
    assert parse_ig_message(e.start_of_frame(True)).packets[0].ig_mode == 0


def test_sync_mode_host_frames_drive_sim_time():
    e = engine()
    for frame in range(1, 6):
        send(e, ship(north=frame), frame=frame, timestamp=frame * 1667, timestamp_valid=True)
        s = e.store.scene
        assert (s.host_frame, s.time.sim_time) == (frame, pytest.approx(frame * 0.01667))
    assert e.store.clock.mode == "host"
    send(e, frame=6, timestamp=0xFFFFFFF0, timestamp_valid=True)
    send(e, frame=7, timestamp=5, timestamp_valid=True)  # the 32-bit timestamp wrapped (after 11.9 h)
    assert e.store.scene.time.sim_time == pytest.approx((2**32 + 5) * 1e-5)
    sof = parse_ig_message(e.start_of_frame(True)).packets[0]
    assert (sof.last_host_frame, sof.ig_mode, sof.ig_frame) == (7, 1, 1)
    assert parse_ig_message(e.start_of_frame(False)).packets[0].ig_mode == 0  # standby until frames flow


def test_database_number_loads_a_scene():
    def database(ready: bool = True) -> int:
        return parse_ig_message(e.start_of_frame(ready)).packets[0].database_number

    e = engine()
    send(e, ship(), database_number=3)  # harbour_night
    assert e.store.scene.location == load_scene("harbour_night").location
    assert e.store.scene.camera.width == 64  # the server's frame size stays
    # CIGI 3.3: Start of Frame reports the number negated while the database loads, until a frame of
    # its state has rendered and the IG is ready (its programs compiled ahead), then the number
    assert database() == -3
    e.store.mark_rendered(e.store.revision)
    assert database(ready=False) == -3
    assert database() == 3
    send(e, frame=2, database_number=99)  # no scene for it: not available, the scene unchanged
    assert database() == -128 and e.store.scene.location == load_scene("harbour_night").location
    send(e, frame=3, database_number=4)
    e.store.mark_rendered(e.store.revision - 1)  # a frame of the state before the load: still loading
    assert database() == -4
    e.store.mark_rendered(e.store.revision)
    assert database() == 4


def test_rate_control_extrapolates_between_host_frames():
    e = engine()
    send(e, ship(), RateControl(entity_id=1, x_rate=5.0))  # 5 m/s north (world axes)
    e.store.clock.change(type(e.store.clock.state())(mode="free", sim_time=0.0, rate=1.0, paused=True))
    y0 = e.store.scene.entities[0].position[1]
    e.session.entities[1].updated_at = e.store.scene.time.sim_time - 2.0  # 2 s since the host's last frame
    assert e.extrapolate()
    assert e.store.scene.entities[0].position[1] == pytest.approx(y0 + 10.0)


def _sea_engine() -> CigiEngine:
    e = engine({"ocean": {"enabled": True, "sea_state": 5}})
    send(e, frame=1, timestamp=123_456, timestamp_valid=True)  # a fixed sim_time: the query and REST agree on it
    return e


@pytest.mark.parametrize("order", [">", LITTLE])
def test_hat_hot_over_the_sea_equals_the_rest_query(order):
    e = _sea_engine()
    frame = LocalFrame.of(e.store.scene.location)
    points = [(LAT0 + 0.0003 * i, LON0 - 0.0005 * i) for i in range(8)]
    send(e, *[HatHotRequest(request_id=i, request_type=i % 3, lat=lat, lon=lon, alt=25.0)
              for i, (lat, lon) in enumerate(points)], frame=2, timestamp=123_456, timestamp_valid=True, order=order)
    answers = parse_ig_message(e.start_of_frame(True)).packets[1:]
    rest = water_height(e.store.scene, {"points": [list(frame.to_enu(lat, lon, 0)[:2]) for lat, lon in points]})
    for i, packet in enumerate(answers):
        hot = rest["height"][i]
        assert packet.request_id == i and packet.valid
        if isinstance(packet, HatHotExtendedResponse):
            nx, ny, nz = rest["normal"][i]
            assert (packet.hot, packet.hat, packet.material_code) == (pytest.approx(hot, abs=1e-3),
                                                                       pytest.approx(25.0 - hot, abs=1e-3), 1)
            assert packet.normal_elevation == pytest.approx(np.degrees(np.arcsin(nz)), abs=1e-3)
        else:
            assert isinstance(packet, HatHotResponse)
            assert packet.height == pytest.approx(25.0 - hot if packet.response_type == 0 else hot, abs=1e-3)
    assert len({round(p.hot if hasattr(p, "hot") else 0, 3) for p in answers}) > 1  # waves, not a flat plane


def test_hat_hot_ground_and_entities_and_line_of_sight():
    e = engine({"ground": {"level": -0.5}})
    send(e, ship(type_=3, alt=2.0))  # a 1 m crate at 2 m
    send(e, HatHotRequest(request_id=1, request_type=1, lat=LAT0, lon=LON0, alt=10.0),
         HatHotRequest(request_id=2, request_type=0, lat=LAT0 + 0.001, lon=LON0, alt=10.0),
         HatHotRequest(request_id=3, request_type=0, entity_relative=True, entity_id=1, alt=-20.0),
         LosSegmentRequest(request_id=4, source_lat=LAT0 - 0.0001, source_lon=LON0, source_alt=2.5,
                           destination_lat=LAT0 + 0.0001, destination_lon=LON0, destination_alt=2.5),
         LosVectorRequest(request_id=5, source_lat=LAT0 + 0.001, source_lon=LON0, source_alt=10.0,
                          elevation=-90.0, max_range=100.0),
         LosVectorRequest(request_id=6, source_lat=LAT0 + 0.001, source_lon=LON0, source_alt=10.0,
                          elevation=45.0, max_range=100.0), frame=2)
    hot, hat, above, seg, down, up = parse_ig_message(e.start_of_frame(True)).packets[1:]
    assert hot.height == pytest.approx(3.0) and hat.height == pytest.approx(10.5)
    assert above.height == pytest.approx(22.0 + 0.5)  # 20 m above the crate (at 2 m): its own box is not under it
    start = LocalFrame.of(e.store.scene.location).to_enu(LAT0 - 0.0001, LON0, 0)[1]
    assert isinstance(seg, LosResponse) and seg.valid and seg.entity_valid and seg.entity_id == 1
    assert seg.range == pytest.approx(-start - 0.5, abs=1e-6)
    assert down.valid and not down.entity_valid and down.range == pytest.approx(10.5)
    assert up.visible and not up.valid


def test_docs_settings_table_is_current():
    from pathlib import Path

    from igserver.protocol.settings import settings_table

    doc = (Path(__file__).resolve().parents[1] / "docs" / "cigi.md").read_text(encoding="utf-8")
    assert settings_table("cigi") in doc, "docs/cigi.md settings table out of date: paste settings_table('cigi')"
