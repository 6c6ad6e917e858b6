"""Service latency of two checkouts, interleaved: a server from each in turn (``python -m igserver.protocol``
with that checkout first on PYTHONPATH), the same client against both (``latency_bench``: ws, http and
ws-stream), R rounds alternating. Prints each round and, per checkout and mode, the median over rounds of
the end-to-end p50 in ms and in frames (each round's end-to-end p50 over its own render p50, which takes
out most of a shared machine's drift), and the saturated stream's frames/s times its render p50 (1 = draws
back to back).

    git worktree add --detach /tmp/before <commit>
    PYTHONPATH=$PWD .venv/bin/python scripts/bench_service_ab.py /tmp/before $PWD 100 5 640x360
"""
import os
import statistics
import sys

from igserver.client.core import latency_bench, summarize
from igserver.protocol.bench import server_process

a, b, frames, rounds = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
width, height = (int(v) for v in (sys.argv[5] if len(sys.argv) > 5 else "640x360").split("x"))
MODES = ("ws", "http", "ws-stream")
runs: dict = {}
for r in range(rounds):
    for label, path in (("A", a), ("B", b)) if r % 2 == 0 else (("B", b), ("A", a)):
        os.environ["PYTHONPATH"] = path  # the server's checkout; this process keeps its own client
        with server_process(width, height) as url:
            for mode in MODES:
                s = summarize(latency_bench(url, frames, mode=mode))
                runs.setdefault((label, mode), []).append(s)
                print(f"round {r} {label} {mode:9s} e2e p50 {s['e2e_p50']:.1f} ms  render p50 {s['render_p50']:.1f} ms"
                      + (f"  {s['fps']:.1f} frames/s" if "fps" in s else ""), flush=True)
print(f"\nA = {a}, B = {b}: medians over {rounds} rounds")
for mode in MODES:
    for label in ("A", "B"):
        ss = runs[(label, mode)]
        ms = statistics.median(s["e2e_p50"] for s in ss)
        in_frames = statistics.median(s["e2e_p50"] / s["render_p50"] for s in ss)
        rate = (f"  stream rate x render {statistics.median(s['fps'] * s['render_p50'] / 1e3 for s in ss):.2f}"
                if all("fps" in s for s in ss) else "")
        print(f"{mode:9s} {label}: e2e p50 {ms:.1f} ms = {in_frames:.2f} frames{rate}")
