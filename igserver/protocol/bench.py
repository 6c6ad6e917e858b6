"""``igserver bench --service``: end-to-end latency through a real server on loopback.

Starts ``python -m igserver.protocol`` in its own process (so client and server do not share a GIL),
then, at the requested size, measures state sent -> frame of that state received, one frame at a
time, over the WebSocket and over POST /v1/render, and with a host that sends a state every
1/``--rate`` s without waiting (``ws-stream``: the stream saturated, frames in flight, each frame
timed from the sending of the state it shows). Each frame carries its render time (render
process) and encode time (server), measured in the same run; the difference is the service overhead
(decode, validate, IPC to the render process and back, framing, loopback).
It also compares the JPEG encoders on a rendered frame.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import socket
import subprocess
import sys
import time

import numpy as np

from ..scene.model import PRESET_NAMES


def free_port() -> int:
    with contextlib.closing(socket.socket(socket.AF_INET, socket.SOCK_STREAM)) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def server_command(width: int, height: int, scene: str | None, port: int, preset: str | None = None,
                   rehearse: bool = True) -> list[str]:
    """The command line of the benched server (``igserver serve`` on loopback)."""
    command = [sys.executable, "-m", "igserver.protocol", "--port", str(port), "--width", str(width),
               "--height", str(height)]
    if not rehearse:
        command.append("--no-rehearse")
    if scene:
        command += ["--scene", scene]
    if preset:
        command += ["--preset", preset]
    return command


@contextlib.contextmanager
def server_process(width: int, height: int, scene: str | None = None, port: int | None = None,
                   target_fps: float = 0.0, preset: str | None = None, rehearse: bool = True):
    """A real igserver on loopback in a child process; yields its URL once /v1/ready says so."""
    from igserver.client import IGClient

    port = port or free_port()
    command = server_command(width, height, scene, port, preset, rehearse)
    env = os.environ.copy()
    if target_fps:  # the server's setting for the scene's quality.target_fps
        env["IGSERVER_TARGET_FPS"] = str(target_fps)
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    url = f"http://127.0.0.1:{port}"
    try:
        with IGClient(url) as ig:
            deadline = time.monotonic() + 300
            while True:
                if process.poll() is not None:
                    raise RuntimeError(f"server exited: {process.stderr.read().decode()[-2000:]}")
                try:
                    if ig.ready().get("ready"):
                        break
                except Exception:
                    pass
                if time.monotonic() > deadline:
                    raise TimeoutError("server not ready")
                time.sleep(0.2)
        yield url
    finally:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()


def run_service_bench(argv: list[str] | None = None) -> int:
    from igserver.client import IGClient
    from igserver.client.latency import format_summary, latency_bench, summarize

    from .imaging import compare_jpeg_encoders

    parser = argparse.ArgumentParser(prog="igserver bench --service")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--scene", default=None, help="scene file or name (default: built-in defaults)")
    parser.add_argument("--modes", default="ws,http,ws-stream",
                        help="comma-separated: ws, http, ws-stream, mjpeg (the stream's rate and operating points), "
                        "mjpeg-fire (the stream when a fire starts halfway through)")
    parser.add_argument("--target-fps", type=float, default=0.0,
                        help="the frame rate the started server holds (quality.target_fps; 0 = off)")
    parser.add_argument("--preset", choices=PRESET_NAMES, default=None,
                        help="the started server's quality preset for its scene (auto: the controller's rungs too)")
    parser.add_argument("--rate", type=float, default=60.0, help="ws-stream: states sent per second")
    parser.add_argument("--no-rehearse", dest="rehearse", action="store_false",
                        help="the started server skips compiling ahead (its setting rehearse = false)")
    parser.add_argument("--url", default=None, help="bench a running server instead of starting one")
    parser.add_argument("--json", action="store_true", help="print the summaries as JSON")
    args = parser.parse_args(argv)

    with contextlib.ExitStack() as stack:
        url = args.url or stack.enter_context(
            server_process(args.width, args.height, args.scene, target_fps=args.target_fps, preset=args.preset,
                           rehearse=args.rehearse))
        with IGClient(url) as ig:
            ready = ig.wait_ready()
            raw = ig.get_frame("raw")
        rgba = np.frombuffer(raw.data, np.uint8).reshape(raw.height, raw.width, 4)
        summaries = [summarize(latency_bench(url, args.frames, mode=mode, rate_hz=args.rate))
                     for mode in args.modes.split(",")]

    encoders = compare_jpeg_encoders(rgba)
    if args.json:
        print(json.dumps({"renderer": ready.get("renderer"), "size": [raw.width, raw.height],
                          "target_fps": args.target_fps,
                          "latency": summaries, "jpeg": encoders}, indent=2))
        return 0
    print(f"igserver service bench: {raw.width}x{raw.height}, {ready.get('renderer')}, loopback")
    for summary in summaries:
        print(format_summary(summary))
    for name, r in encoders.items():
        print(f"jpeg {name:10s}: median {r['median_ms']:.2f} ms  p99 {r['p99_ms']:.2f} ms  {r['bytes']} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(run_service_bench())
