"""25,000 (IGSERVER_CIGI_FUZZ_N) random, truncated and lying datagrams through the parser and the mapper: nothing escapes,
a rejected datagram changes neither the scene nor the session, and every datagram is counted."""

from __future__ import annotations

import os
import random
import time

import pytest

from helpers import tiny
from igserver.cigi.datagram import build
from igserver.cigi.engine import CigiEngine
from igserver.cigi.packets_host import HOST_PACKETS, EntityControl, IGControl
from igserver.protocol.metrics import ServiceMetrics
from igserver.protocol.state import StateStore
from test_cigi_codec import random_packet

# 25,000 datagrams (~3 s) in the suite: every rejection kind shows (the rarest, version and non-finite,
# ~50 times each); IGSERVER_CIGI_FUZZ_N=1000000 for a longer run (docs/operations.md, Fuzzing)
N = int(os.environ.get("IGSERVER_CIGI_FUZZ_N", "25000"))


def datagrams(rng: random.Random, n: int):
    """Valid messages (so there is state to damage), then their truncations, lies, flips and noise."""
    classes = [c for c in HOST_PACKETS.values() if c is not IGControl]
    pool = []
    for _ in range(200):
        packets = [IGControl(host_frame=rng.randrange(2**32), ig_mode=1)]
        packets += [EntityControl(entity_id=rng.randrange(4), entity_type=rng.randrange(6), lat=59.93, lon=30.31)]
        packets += [random_packet(rng.choice(classes), rng) for _ in range(rng.randrange(3))]
        pool.append(build(packets, rng.choice("<>")))
    # mostly what must be rejected; a tenth are mutations that can still be valid messages (they apply)
    mix = [0] * 4 + [1] * 5 + [3] * 5 + [7] * 2 + [5, 6, 8, 9]
    for i in range(n):
        base = bytearray(rng.choice(pool))
        kind = mix[i % len(mix)]
        if kind == 0:  # noise
            yield bytes(rng.randrange(256) for _ in range(rng.randrange(0, 120)))
        elif kind in (1, 2):  # truncated anywhere
            yield bytes(base[:rng.randrange(len(base))])
        elif kind in (3, 4):  # a size field lies (the first packet's, or one further on)
            offsets = [0]
            offset = 0
            while offset + 1 < len(base) and base[offset + 1]:
                offset += base[offset + 1]
                if offset < len(base):
                    offsets.append(offset)
            at = rng.choice(offsets)
            if at + 1 < len(base):
                base[at + 1] = rng.choice([0, 1, 3, 7, 9, 255, max(0, base[at + 1] + rng.choice((-8, 8)))])
            yield bytes(base)
        elif kind == 5:  # an unknown packet id, or a packet id swapped for another known one
            at = rng.randrange(24, max(25, len(base))) if len(base) > 24 else 0
            if at < len(base):
                base[at] = rng.randrange(256)
            yield bytes(base)
        elif kind == 6:  # NaN / Inf in a float (bit patterns all-ones exponent)
            at = rng.randrange(len(base) - 4)
            base[at:at + 4] = rng.choice([b"\x7f\xc0\x00\x00", b"\x7f\x80\x00\x00", b"\xff\xf8\x00\x00"])
            yield bytes(base)
        elif kind == 7:  # trailing garbage
            yield bytes(base) + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 9)))
        elif kind == 8:  # a flipped byte in a packet header: id, size, the bit-packed words
            at = rng.randrange(0, len(base), 8) + rng.randrange(8)
            base[min(at, len(base) - 1)] ^= 1 << rng.randrange(8)
            yield bytes(base)
        else:  # a few flipped bytes anywhere (some of these are still valid messages)
            for _ in range(rng.randrange(1, 4)):
                base[rng.randrange(len(base))] = rng.randrange(256)
            yield bytes(base)


# A numeric warning is a value the IG did not expect: here it fails the fuzz (a line of sight between two
# heights near the float64 limit overflowed their product).
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_fuzz_no_crash_no_change_from_rejects_all_counted():
    store = StateStore(tiny())
    metrics = ServiceMetrics()
    engine = CigiEngine(store, metrics)
    rng = random.Random(20261127)
    accepted = rejected = 0
    t0 = time.perf_counter()
    for data in datagrams(rng, N):
        revision, session, scene = store.revision, engine.session, store._scene
        if engine.handle(data) is None:
            rejected += 1
            assert store.revision == revision and engine.session is session and store._scene is scene
        else:
            accepted += 1
    elapsed = time.perf_counter() - t0
    value = metrics.value
    assert accepted + rejected == N and rejected > 0.8 * N
    assert value("igserver_cigi_datagrams_total", result="rejected") == rejected
    assert value("igserver_cigi_datagrams_total", result="accepted") == accepted
    kinds = ("short", "size", "first_packet", "magic", "version", "non_finite", "out_of_range", "validation",
             "unknown_entity")
    counted = {k: value("igserver_cigi_rejected_total", kind=k) or 0.0 for k in kinds}
    assert sum(counted.values()) == rejected, counted
    assert all(counted[k] > 0 for k in ("short", "size", "first_packet", "non_finite", "out_of_range"))
    print(f"{N} datagrams in {elapsed:.1f} s: {accepted} accepted, rejected {counted}")
