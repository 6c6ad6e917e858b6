"""CIGI through the real server: the host emulator (clients/cigi_host.py) over loopback UDP, Start of
Frame from Standby to Operate, synchronous mode frame-exact, senders not allowed dropped, and the
packets cross-checked against Wireshark's CIGI dissector (tshark; skipped with the reason when missing)."""

from __future__ import annotations

import random
import shutil
import socket
import struct
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import httpx
import pytest

from helpers import tiny
from igserver.cigi.codec import BIG, LITTLE
from igserver.cigi.datagram import build, parse, parse_ig_message
from igserver.cigi.packets_host import HOST_PACKETS, IGControl
from igserver.cigi.packets_ig import IG_PACKETS, StartOfFrame
from igserver.cigi.pcap import PcapWriter
from igserver.protocol.settings import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import load_scene
from test_cigi_codec import random_packet

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "clients"))
import cigi_host  # noqa: E402  (the example host program, not part of the package)

TSHARK = shutil.which("tshark")


def host_socket(address: str = "127.0.0.1") -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((address, 0))
    return sock


@pytest.fixture(scope="module")
def ig():
    """A server with CIGI on, sending to a socket of the test's from its first SOF (cigi_host fixed)."""
    sock = host_socket()
    settings = ServerSettings(cigi=True, cigi_port=0, cigi_host="127.0.0.1", cigi_host_port=sock.getsockname()[1],
                              cigi_allow=["127.0.0.1"])
    server = LoopbackServer(tiny({"ocean": {"enabled": True}}), settings).start()
    server.cigi_port = server.runtime.cigi.transport.get_extra_info("sockname")[1]
    server.host_sock = sock
    yield server
    server.stop()
    sock.close()


def drain(sock: socket.socket) -> list[StartOfFrame]:
    sock.settimeout(0.05)
    out = []
    while True:
        try:
            data, _ = sock.recvfrom(65536)
        except socket.timeout:
            return out
        out += [p for p in parse_ig_message(data).packets if isinstance(p, StartOfFrame)]


def test_standby_while_starting_then_operate(ig):
    early = drain(ig.host_sock)  # SOFs sent while the render process started (buffered by the socket)
    assert early and early[0].ig_mode == 0
    time.sleep(0.3)
    assert drain(ig.host_sock)[-1].ig_mode == 1  # ready: Operate


def test_emulator_scenario_drives_the_state(ig):
    # 5 s: the fire starts at 2 s, and its first frame compiles the fire's programs (1.5 s on llvmpipe
    # with a cold shader cache, more on a loaded machine): no frame, so no answer, until it is drawn
    summary = cigi_host.run(("127.0.0.1", ig.cigi_port), seconds=5.0, rate=30.0, sock=ig.host_sock)
    scene = ig.runtime.store.scene
    assert [e.id for e in scene.entities] == ["cigi.1", "cigi.2"] and scene.entities[0].model == "patrol_boat"
    assert [e.id for e in scene.effects] == ["cigi.2.fx1"] and scene.effects[0].active
    assert scene.weather.precipitation.type == "rain" and scene.atmosphere.visibility == 3000.0
    assert scene.host_frame == 149 and scene.camera.position[1] < scene.entities[0].position[1]
    assert summary.sof and summary.sof[-1].ig_mode == 1 and summary.sof[-1].last_host_frame >= 60
    ids = sorted({r.request_id for r in summary.responses})
    assert len(ids) >= 25 and all(r.valid and r.material_code == 1 for r in summary.responses)
    state = httpx.get(ig.url + "/v1/state").json()  # the same state over REST
    assert [e["id"] for e in state["entities"]] == ["cigi.1", "cigi.2"]
    metrics = ig.runtime.metrics
    assert metrics.value("igserver_cigi_datagrams_total", result="accepted") >= 150
    assert metrics.value("igserver_cigi_packets_total", packet="Component Control") == 1
    # Every SOF's delay from its frame start is measured into /metrics (the figure itself is a
    # benchmark's: a loaded machine makes the event loop wait for the CPU or the GIL, so no bound here)
    count = metrics.value("igserver_cigi_sof_delay_seconds_count")
    assert count and metrics.value("igserver_cigi_sof_delay_seconds_bucket", le="+Inf") >= count  # SOFs go on


def test_synchronous_lockstep_is_frame_exact(ig):
    shown: list[tuple[int, float]] = []
    pump = ig.runtime.pump
    publish = pump.publish

    def record(encoded):
        shown.append((encoded.host_frame, encoded.sim_time))
        publish(encoded)

    pump.publish = record
    first, rate = 10_000, 20.0  # host frames 10000...: no state before this test had them
    try:
        summary = cigi_host.run(("127.0.0.1", ig.cigi_port), seconds=1.0, rate=rate, sync=True, sock=ig.host_sock,
                                first_frame=first)
    finally:
        pump.publish = publish
    frames = [(n - first, t) for n, t in shown if first <= n < first + rate]
    assert len({n for n, _ in frames}) >= 5, shown
    for n, t in frames:  # each frame shows exactly host frame n, at its timestamp
        assert t == pytest.approx(int(n / rate * 100_000) * 1e-5, abs=1e-9)
    assert [n for n, _ in frames] == sorted(n for n, _ in frames)
    assert summary.sof[-1].last_host_frame == first + rate - 1
    assert ig.runtime.store.clock.mode == "host"
    ig.runtime.store.clock.mode = "free"  # hand the clock back for the tests after this one


def test_a_database_load_compiles_ahead_and_reports_its_progress():
    """IG Control's Database Number loads a scene: while it loads (its first frame, then the programs it
    may come to need compiled ahead, as at the start: render/rehearsal.py) Start of Frame says -N and
    Standby, and /v1/ready says why; then N and Operate."""
    sock = host_socket()
    settings = ServerSettings(cigi=True, cigi_port=0, cigi_host="127.0.0.1", cigi_host_port=sock.getsockname()[1],
                              cigi_allow=["127.0.0.1"])
    server = LoopbackServer(tiny(), settings).start()
    try:
        port = server.runtime.cigi.transport.get_extra_info("sockname")[1]
        deadline = time.monotonic() + 60
        while not (drain(sock) or [None])[-1] or not server.runtime.ready():
            assert time.monotonic() < deadline
        rehearsals = []
        rehearse = server.service.rehearse
        server.service.rehearse = lambda scene=None: rehearsals.append(scene) or rehearse(scene)
        sock.sendto(build([IGControl(host_frame=1, database_number=4)]), ("127.0.0.1", port))  # sea_beaufort5
        seen, not_ready = [], set()
        while not seen or (seen[-1].database_number, seen[-1].ig_mode) != (4, 1):
            assert time.monotonic() < deadline + 120, seen[-5:]
            seen += drain(sock)
            reply = httpx.get(server.url + "/v1/ready", timeout=5)
            if reply.status_code == 503:
                not_ready.add(reply.json()["error"].split(" (")[0])
        states = [(s.database_number, s.ig_mode) for s in seen]
        assert states[0] == (-4, 0) and set(states) <= {(-4, 0), (-4, 1), (4, 1)}, states
        assert (-4, 0) in states and not_ready <= {"compiling ahead the programs of fires, lights, rain, snow and "
                                                    "the sea's states"}
        assert len(rehearsals) == 1 and rehearsals[0].ocean == load_scene("sea_beaufort5").ocean  # the loaded scene
    finally:
        server.stop()
        sock.close()


def test_senders_not_allowed_are_dropped_and_counted(ig):
    stranger = host_socket("127.0.0.2")
    before = ig.runtime.metrics.value("igserver_cigi_datagrams_total", result="dropped") or 0.0
    revision = ig.runtime.store.revision
    stranger.sendto(build([IGControl(host_frame=7)]), ("127.0.0.1", ig.cigi_port))
    time.sleep(0.3)
    stranger.close()
    assert ig.runtime.metrics.value("igserver_cigi_datagrams_total", result="dropped") == before + 1
    assert ig.runtime.store.revision == revision


def test_non_loopback_bind_needs_an_allow_list():
    with pytest.raises(ValueError, match="cigi_allow"):
        ServerSettings(cigi=True, cigi_bind="0.0.0.0")
    assert ServerSettings(cigi=True, cigi_bind="0.0.0.0", cigi_allow="10.1.2.3").cigi_allow == ["10.1.2.3"]


# -- the independent check: Wireshark's dissector reads every field as we wrote it -------------------------

PAYLOAD = 42  # bytes of Ethernet + IPv4 + UDP headers before the CIGI message in a pcap frame


def slots(cls):
    """(offset, size, code, name or bit fields) of every slot of a packet's layout."""
    offset = 2
    for slot in cls.LAYOUT:
        size = struct.calcsize(">" + slot[1])
        yield offset, size, slot[1], (slot[2] if len(slot) > 2 else slot[0])
        offset += size


def mask_of(showname: str) -> tuple[int, int] | None:
    """(shift, width) of a bit field from tshark's ``.... ..01 = Name`` notation."""
    pattern = showname.split(" = ", 1)[0].replace(" ", "")
    if len(pattern) not in (8, 16, 32) or set(pattern) - set(".01"):
        return None
    bits = [i for i, c in enumerate(reversed(pattern)) if c != "."]
    return (bits[0], len(bits)) if bits else None


def compare_message(fields: list, packets: list, base: int, order: str) -> set[str]:
    """Check each tshark field of one message against the packet we decoded at its offset; returns the
    (packet, field) names checked."""
    checked = set()
    starts, offset = [], 0
    for packet in packets:
        starts.append((offset, packet))
        offset += packet.SIZE
    for field in fields:
        name, show, pos = field.get("name"), field.get("show"), field.get("pos")
        if pos is None or not show or len(field) or name in ("cigi.packet_id", "cigi.packet_size", "cigi.byte_swap",
                                                   "cigi.frame_size", "cigi.port", "cigi.srcport", "cigi.destport"):
            continue
        rel = int(pos) - base
        start, packet = max((s for s in starts if s[0] <= rel), key=lambda s: s[0])
        rel -= start
        if name == "cigi.version":
            assert int(show) == packet.version
            continue
        for offset, size, code, what in slots(type(packet)):
            if offset != rel:
                continue
            if isinstance(what, tuple):
                mask = mask_of(field.get("showname", ""))
                bit = next(b for b in what if (b[1], b[2]) == mask)
                assert int(show) == int(getattr(packet, bit[0])), (name, show, packet)
                checked.add(f"{packet.NAME}.{bit[0]}")
            else:
                ours = getattr(packet, what)
                if code in "fd":
                    assert float(show) == pytest.approx(ours, rel=1e-5 if code == "f" else 1e-12, abs=1e-30), (
                        name, show, packet)
                elif ":" in show:  # component data words: shown as the bytes on the wire
                    assert bytes.fromhex(show.replace(":", "")) == struct.pack(order + code, ours), (name, show)
                else:
                    assert int(show, 0) == ours, (name, show, packet)
                checked.add(f"{packet.NAME}.{what}")
            break
        else:
            raise AssertionError(f"tshark shows {name} at offset {rel} of {packet.NAME}: no field of ours there")
    return checked


def tshark_check(pcap: Path, ports: tuple[int, ...]) -> set[str]:
    args = [TSHARK, "-r", str(pcap), "-T", "pdml"]
    for port in ports:
        args += ["-d", f"udp.port=={port},cigi"]
    root = ET.fromstring(subprocess.run(args, capture_output=True, check=True, timeout=120).stdout)
    checked: set[str] = set()
    for frame in root.iter("packet"):
        raw = bytes.fromhex(next(f.get("value") for f in frame.iter("field") if f.get("name") == "udp.payload")) \
            if any(f.get("name") == "udp.payload" for f in frame.iter("field")) else None
        proto = next((p for p in frame.iter("proto") if p.get("name") == "cigi"), None)
        assert proto is not None, "tshark did not take a datagram for CIGI"
        base = int(proto.get("pos"))
        if raw is None:
            raw = bytes.fromhex(proto.get("value") or "")
        message = parse_ig_message(raw) if raw[0] == StartOfFrame.ID else parse(raw)
        checked |= compare_message(list(proto.iter("field")), message.packets, base, message.order)
    return checked


def all_fields(classes) -> set[str]:
    out = set()
    for cls in classes:
        for _, _, _, what in slots(cls):
            if isinstance(what, tuple):
                out |= {f"{cls.NAME}.{b[0]}" for b in what}
            elif what and what not in ("magic", "version"):
                out.add(f"{cls.NAME}.{what}")
    return out


@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (scripts/test.sh installs it when root)")
@pytest.mark.parametrize("order", [BIG, LITTLE], ids=["big", "little"])
def test_tshark_reads_every_packet_as_we_do(tmp_path, order):
    rng = random.Random(33)
    pcap = tmp_path / "all.pcap"
    with PcapWriter(pcap) as capture:
        for _ in range(3):
            for cls in HOST_PACKETS.values():
                first = random_packet(IGControl, rng)
                # the dissector picks its 3.x layouts by the minor version, and takes a datagram whose IG mode
                # is 3 (offline maintenance) for something else than CIGI
                first.version, first.minor_version, first.ig_mode = 3, 3, rng.randrange(3)
                packets = [first] + ([] if cls is IGControl else [random_packet(cls, rng)])
                capture.add(build(packets, order), ("127.0.0.1", 8005), ("127.0.0.1", 8004))
            for cls in IG_PACKETS.values():
                first = random_packet(StartOfFrame, rng)
                first.version, first.minor_version, first.ig_mode = 3, 3, rng.randrange(3)
                packets = [first] + ([] if cls is StartOfFrame else [random_packet(cls, rng)])
                capture.add(build(packets, order), ("127.0.0.1", 8004), ("127.0.0.1", 8005))
    checked = tshark_check(pcap, (8004, 8005))
    missing = all_fields(list(HOST_PACKETS.values()) + list(IG_PACKETS.values())) - checked
    assert not missing, f"fields tshark did not show: {sorted(missing)}"


@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (scripts/test.sh installs it when root)")
def test_tshark_agrees_with_a_captured_session(ig, tmp_path):
    pcap = tmp_path / "session.pcap"
    with PcapWriter(pcap) as capture:
        summary = cigi_host.run(("127.0.0.1", ig.cigi_port), seconds=2.2, rate=30.0, sock=ig.host_sock,
                                capture=capture, order=LITTLE)  # past 2 s: the fire's Component Control
    assert summary.sof and summary.responses
    checked = tshark_check(pcap, (ig.cigi_port, ig.host_sock.getsockname()[1]))
    assert {"Start of Frame.ig_frame", "HAT/HOT Extended Response.hot", "Entity Control.lat",
            "Component Control.data2", "IG Control.host_frame"} <= checked


def test_hat_over_the_sea_equals_the_rest_query_through_the_server(ig):
    from igserver.cigi.geo import LocalFrame
    from igserver.cigi.packets_host import HatHotRequest
    from igserver.cigi.packets_ig import HatHotExtendedResponse

    lat, lon = 59.9312, 30.3087
    drain(ig.host_sock)
    message = build([IGControl(host_frame=500, timestamp=4_321_000, timestamp_valid=True),
                     HatHotRequest(request_id=77, request_type=2, lat=lat, lon=lon, alt=30.0)])
    ig.host_sock.sendto(message, ("127.0.0.1", ig.cigi_port))
    ig.host_sock.settimeout(5.0)
    answer = None
    while answer is None:
        data, _ = ig.host_sock.recvfrom(65536)
        answer = next((p for p in parse_ig_message(data).packets if isinstance(p, HatHotExtendedResponse)), None)
    scene = ig.runtime.store.scene
    x, y, _ = LocalFrame.of(scene.location).to_enu(lat, lon, 0.0)
    rest = httpx.post(ig.url + "/v1/query/water-height", json={"points": [[x, y]], "sim_time": 43.21}).json()
    assert answer.valid and answer.material_code == 1
    assert answer.hot == pytest.approx(rest["height"][0], abs=1e-3)
    assert answer.hat == pytest.approx(30.0 - rest["height"][0], abs=1e-3)
    ig.runtime.store.clock.mode = "free"
