"""A host simulator's loop against igserver: the README's host program, runnable.

    .venv/bin/python clients/host_loop.py --url http://127.0.0.1:8600 [--token T] [--frames 30] [--out frame.jpg]

Connects, sets camera, time and weather in one patch, starts a fire through the effects route (it fades
in over its `fade` seconds of the IG clock), then sends one state per host frame over the WebSocket and
reads the frames back: each frame names the `host_frame` of the state it shows, so a host can tell how far
behind the picture is. The last frame is saved as JPEG.
"""

from __future__ import annotations

import argparse
import os

from igserver.client import IGClient, IGError

FIRE = {"id": "fire2", "type": "fire", "position": [-60.0, -80.0, 2.0], "diameter": 2.0, "emits_smoke": True}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", default=os.environ.get("IGSERVER_URL", "http://127.0.0.1:8600"))
    ap.add_argument("--token", default=os.environ.get("IGSERVER_TOKEN"), help="the server's bearer token, if any")
    ap.add_argument("--frames", type=int, default=30, help="host frames to send")
    ap.add_argument("--out", default="frame.jpg", help="where the last frame is saved")
    args = ap.parse_args(argv)

    with IGClient(args.url, token=args.token) as ig:
        ig.wait_ready()  # the first start precomputes the sky tables
        ig.patch_state({  # any subset of the scene; the rest stays
            "host_frame": 1,
            "camera": {"position": [0.0, -120.0, 6.0], "heading": 288.0, "pitch": 1.0},  # m ENU, deg
            "time": {"utc": "2026-09-15T16:05:00Z"},
            "weather": {"wind_speed": 8.0, "wind_direction": 250.0,  # m/s at 10 m; deg, blowing from
                        "precipitation": {"type": "rain", "rate": 2.0}},  # mm/h
            "atmosphere": {"visibility": 8000.0},  # m
        })
        try:
            ig.add_effect(FIRE)
        except IGError as exc:
            if exc.status != 409:  # 409: a fire of that id burns already (a second run of this program)
                raise
            ig.patch_effect(FIRE["id"], {"active": True})
        frame = None
        with ig.stream(credits=2) as stream:  # WebSocket, msgpack both ways
            for n in range(2, 2 + args.frames):  # one state per host frame
                stream.send_patch({"host_frame": n, "camera": {"heading": 288.0 + 0.1 * n}})
                frame = stream.recv()  # the newest frame; acknowledged for you
                print(f"host frame {frame.host_frame}: IG frame {frame.frame}, {frame.render_ms:.0f} ms")
    if frame is not None:
        with open(args.out, "wb") as f:
            f.write(frame.data)  # JPEG bytes; frame.rgba() decodes them
        print(f"wrote {args.out} ({frame.width}x{frame.height})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
