"""Soak the server and report whether memory returns to its baseline (docs/operations.md, Memory).

    .venv/bin/python scripts/soak.py [--frames 3000]

Starts ``python -m igserver.protocol`` on a small scene with a scratch asset directory of 100 profile
images, then for ``--frames`` frames: fetches frames, grows the frame to 960x540 for 10 of every 200 frames
(a new shared-memory ring each way), names a different profile asset every 10 frames, and keeps two WebSocket
clients that ask for raw frames and never read. At the end it returns to the small frame, closes the
clients and reports RSS of both processes (first/peak/last, and every 1000 frames), the ring segments
each process maps and the deleted segments still mapped.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import msgpack
from PIL import Image
from websockets.sync.client import connect

SMALL, BIG = (160, 90), (960, 540)


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def ring_segments(pid: int) -> int:
    """Distinct shared-memory ring segments this process has mapped (other servers on the machine excluded)."""
    return len({line.split()[-1] for line in Path(f"/proc/{pid}/maps").read_text().splitlines()
                if "/dev/shm/psm_" in line and "(deleted)" not in line})


def deleted_mapped(pid: int) -> int:
    return sum(1 for line in Path(f"/proc/{pid}/maps").read_text().splitlines()
               if "/dev/shm/psm_" in line and "(deleted)" in line)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=3000)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="igserver-soak-"))
    (work / "profiles").mkdir()
    for i in range(100):
        Image.new("RGBA", (16, 32), (255, 120 + i, 40, 60 + i)).save(work / "profiles" / f"p{i}.png")
    scene = work / "scene.toml"
    scene.write_text(f'[camera]\nwidth = {SMALL[0]}\nheight = {SMALL[1]}\nposition = [0.0, -20.0, 3.0]\n'
                     '[atmosphere]\nmodel = "gradient"\n[[effects]]\nid = "f"\ndiameter = 4.0\n')
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "IGSERVER_ASSETS": str(work), "PYTHONPATH": os.getcwd()}
    server = subprocess.Popen([sys.executable, "-m", "igserver.protocol", "--scene", str(scene), "--port", str(port)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = f"http://127.0.0.1:{port}"
    http = httpx.Client(base_url=url, timeout=120)
    try:
        while True:
            try:
                ready = http.get("/v1/ready")
                if ready.status_code == 200:
                    break
            except httpx.TransportError:
                pass
            time.sleep(0.2)
        render_pid = ready.json()["pid"]
        for _ in range(50):
            http.get("/v1/frame")
        first = (rss_mb(server.pid), rss_mb(render_pid), ring_segments(server.pid), ring_segments(render_pid))
        slow = []
        for _ in range(2):  # raw frames, never read: the server must hold at most one frame each
            ws = connect(f"ws://127.0.0.1:{port}/v1/ws", compression=None, max_size=2**28).__enter__()
            ws.send(msgpack.packb({"type": "hello", "credits": 16, "format": "raw"}))
            slow.append(ws)
        t0 = time.perf_counter()
        peak = first[:2]
        for i in range(args.frames):
            if i % 200 in (0, 10):  # 10 big frames in every 200: a new ring each way
                size = BIG if i % 200 == 0 else SMALL
                http.patch("/v1/state", json={"camera": {"width": size[0], "height": size[1]}}).raise_for_status()
            if i % 10 == 0:
                http.patch("/v1/effects/f", json={"profile": f"p{(i // 10) % 100}"}).raise_for_status()
            assert http.get("/v1/frame").status_code == 200
            if i % 100 == 0:
                peak = (max(peak[0], rss_mb(server.pid)), max(peak[1], rss_mb(render_pid)))
            if i % 1000 == 999:  # at a small-frame point: the trend shows a leak, a plateau does not
                print(f"  after {i + 1} frames: server {rss_mb(server.pid):.0f} MB, render {rss_mb(render_pid):.0f} MB",
                      flush=True)
        elapsed = time.perf_counter() - t0
        http.patch("/v1/state", json={"camera": {"width": SMALL[0], "height": SMALL[1]}}).raise_for_status()
        for ws in slow:
            ws.close()
        for _ in range(20):
            http.get("/v1/frame")
        time.sleep(2)
        last = (rss_mb(server.pid), rss_mb(render_pid), ring_segments(server.pid), ring_segments(render_pid))
        restarts = http.get("/v1/ready").json()["restarts"]
        print(f"frames {args.frames} in {elapsed:.0f} s; restarts {restarts}")
        print(f"server RSS MB   first {first[0]:.0f}  peak {peak[0]:.0f}  last {last[0]:.0f}")
        print(f"render RSS MB   first {first[1]:.0f}  peak {peak[1]:.0f}  last {last[1]:.0f}")
        print(f"ring segments mapped: server first {first[2]} last {last[2]}, render first {first[3]} last {last[3]}; "
              f"deleted segments still mapped: server {deleted_mapped(server.pid)}, render {deleted_mapped(render_pid)}")
    finally:
        http.close()
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
