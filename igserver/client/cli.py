"""``igclient``: the host client from the shell (send, set, state, channels, frame, play, record, effects, bench)."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import httpx

from igserver.scene import load_scene, patch_from_assignments

from .http import IGClient
from .latency import format_summary, latency_bench, summarize
from .wire import DEFAULT_URL, IGError


def _client(args) -> IGClient:
    return IGClient(args.url, token=args.token)


def _cmd_send(args) -> int:
    scene = load_scene(args.scene)
    with _client(args) as ig:
        ig.put_state(scene, minimal=True)
    print(f"sent {args.scene}")
    return 0


def _cmd_set(args) -> int:
    with _client(args) as ig:
        # a list item (effects.0.active=false) is set by sending the whole list with that item changed
        needs_base = any(k.isdigit() for a in args.assignments for k in a.split("=", 1)[0].split("."))
        base = ig.get_state().model_dump(mode="json") if needs_base else None
        reply = ig.patch_state(patch_from_assignments(args.assignments, base=base), minimal=True)
    print(json.dumps(reply))
    return 0


def _cmd_state(args) -> int:
    with _client(args) as ig:
        print(ig.get_state().model_dump_json(indent=2))
    return 0


FRAME_SUFFIXES = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg", ".raw": "raw", ".rgba": "raw"}


def _cmd_frame(args) -> int:
    suffix = Path(args.output).suffix.lower()
    if suffix not in FRAME_SUFFIXES:
        raise ValueError(f"{args.output}: unknown image type {suffix or '(none)'!r}; use .jpg, .png or .raw "
                         "(.raw: RGBA bytes, top row first)")
    fmt = FRAME_SUFFIXES[suffix]
    with _client(args) as ig:
        frame = ig.get_frame(fmt, channel=args.channel)
    Path(args.output).write_bytes(frame.data)
    layout = " RGBA8, top row first" if fmt == "raw" else ""
    shown = f"channel {frame.channel!r}, " if frame.channel else ""
    print(f"{args.output}: {shown}frame {frame.frame}, host_frame {frame.host_frame}, {frame.width}x{frame.height}"
          f"{layout}, render {frame.render_ms:.1f} ms")
    return 0


def _cmd_channels(args) -> int:
    with _client(args) as ig:
        for c in ig.channels():
            name = "(camera)" if c["implicit"] else c["id"]
            print(f"{name}\t{c['width']}x{c['height']}\theading {c['heading']:g} pitch {c['pitch']:g} roll {c['roll']:g}"
                  f"\tfov left {c['fov_left']:g} right {c['fov_right']:g} up {c['fov_up']:g} down {c['fov_down']:g}")
    return 0


def read_scenario(path: str) -> list[dict]:
    """JSON lines, one patch per line; blank lines and lines starting with # or // are comments."""
    patches = []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        text = line.strip()
        if not text or text.startswith(("#", "//")):
            continue
        try:
            patch = json.loads(text)
        except ValueError as exc:
            raise ValueError(f"{path}:{number}: not a JSON patch ({exc.msg}): {text[:60]}") from None
        if not isinstance(patch, dict):
            raise ValueError(f"{path}:{number}: a patch is a JSON object, got {type(patch).__name__}")
        patches.append(patch)
    return patches


def _cmd_play(args) -> int:
    """Scenario file: JSON lines, one patch per line, sent at --rate; host_frame counts up unless given."""
    patches = read_scenario(args.scenario)
    period = 1.0 / args.rate
    with _client(args) as ig:
        host_frame = ig.get_state().host_frame
        start = time.perf_counter()
        for index, patch in enumerate(patches * args.loops):
            patch = dict(patch)
            host_frame = patch.get("host_frame", host_frame + 1)
            patch["host_frame"] = host_frame
            ig.patch_state(patch, minimal=True)
            time.sleep(max(0.0, start + (index + 1) * period - time.perf_counter()))
    print(f"played {len(patches) * args.loops} patches at {args.rate} Hz")
    return 0


def _cmd_record(args) -> int:
    count = 0
    target = args.mjpeg or args.png_dir
    try:
        with _client(args) as ig:
            if args.mjpeg:
                with open(args.mjpeg, "wb") as out:
                    for jpeg in ig.mjpeg(frames=args.frames, fps=args.fps, channel=args.channel):
                        # an .mjpg file of concatenated JPEGs: ffmpeg/ffplay read it with -f mjpeg
                        out.write(jpeg)
                        count += 1
            else:
                folder = Path(args.png_dir)
                folder.mkdir(parents=True, exist_ok=True)
                channels = None if args.channel is None else [args.channel]
                with ig.stream(credits=2, format="png", channels=channels) as stream:
                    for n in range(args.frames or 100):
                        frame = stream.recv()
                        if args.channel is not None:
                            if args.channel not in frame.channels:
                                print(f"{target}: channel {args.channel!r} left the state", file=sys.stderr)
                                break
                            frame = frame.channels[args.channel]
                        (folder / f"frame_{n:05d}_{frame.host_frame}.png").write_bytes(frame.data)
                        count += 1
    except KeyboardInterrupt:  # Ctrl-C is how an open-ended recording ends: keep what was written
        print(f"{target}: stopped after {count} frames", file=sys.stderr)
        return 0
    print(f"{target}: {count} frames")
    return 0


def _cmd_effects(args) -> int:
    with _client(args) as ig:
        action = args.action
        if action == "list":
            effects = ig.effects()
            if not effects:
                print("no effects")
            for e in effects:
                print(f"{e['id']:<20} {e['type']:<8} {'active' if e.get('active') else 'inactive':<8} "
                      f"intensity {e.get('intensity', 1.0):g}")
            return 0
        if not args.id:
            raise ValueError(f"effects {action}: give the effect id")
        if action == "add":
            effect = {**patch_from_assignments(args.fields), "id": args.id}  # type=fire|smoke|gas_burner
            result = ig.add_effect(effect)
        elif action == "start":
            result = ig.patch_effect(args.id, {"active": True})
        elif action == "stop":
            result = ig.delete_effect(args.id)  # fades out
        elif action == "remove":
            result = ig.delete_effect(args.id, immediate=True)
        else:  # set
            result = ig.patch_effect(args.id, patch_from_assignments(args.fields))
    print(json.dumps(result) if result is not None else f"removed {args.id}")
    return 0


def saved_clock(clock: dict) -> dict:
    """The clock change that puts ``clock`` (a GET /v1/clock answer) back: its mode, rate and pause, and its
    sim_time where it stood still (host mode, paused); a running clock runs on from where it is now."""
    change = {key: clock[key] for key in ("mode", "rate", "paused")}
    if clock["mode"] == "host" or clock["paused"]:
        change["sim_time"] = clock["sim_time"]
    return change


def _cmd_bench(args) -> int:
    with _client(args) as ig:
        ig.wait_ready()
        # the benchmark moves the camera and host_frame: the operator's state and clock are put back after it
        saved, clock = ig.get_state().model_dump(mode="json"), ig.clock()
        del saved["time"]["sim_time"]  # the clock's, restored with it (a sim_time in a state takes the clock)
        try:
            if args.width or args.height:
                size = {k: v for k, v in (("width", args.width), ("height", args.height)) if v}
                ig.patch_state({"camera": size}, minimal=True)
            for mode in args.modes.split(","):
                print(format_summary(summarize(latency_bench(args.url, args.frames, mode=mode, token=args.token))))
        finally:
            ig.put_state(saved, minimal=True)
            ig.set_clock(**saved_clock(clock))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="igclient", description="igserver host client")
    parser.add_argument("--url", default=os.environ.get("IGSERVER_URL", DEFAULT_URL),
                        help=f"server URL (default $IGSERVER_URL or {DEFAULT_URL})")
    parser.add_argument("--token", default=os.environ.get("IGSERVER_TOKEN"),
                        help="bearer token (default $IGSERVER_TOKEN)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("send", help="replace the state with a scene file")
    p.add_argument("scene")
    p.set_defaults(run=_cmd_send)

    p = sub.add_parser("set", help="patch fields: igclient set camera.pitch=5 weather.wind_speed=12 effects.0.active=false")
    p.add_argument("assignments", nargs="+", metavar="PATH=VALUE")
    p.set_defaults(run=_cmd_set)

    p = sub.add_parser("state", help="print the current state")
    p.set_defaults(run=_cmd_state)

    p = sub.add_parser("frame", help="save a frame of the current state (.jpg, .png or .raw RGBA)")
    p.add_argument("output")
    p.add_argument("--channel", help="the channel's image (igclient channels lists them; default: the first)")
    p.set_defaults(run=_cmd_frame)

    p = sub.add_parser("channels", help="list the state's channels (size, attitude offsets, half-angles)")
    p.set_defaults(run=_cmd_channels)

    p = sub.add_parser("play", help="play a scenario (JSON lines of patches; # comments) at a rate")
    p.add_argument("scenario")
    p.add_argument("--rate", type=float, default=30.0, help="patches per second")
    p.add_argument("--loops", type=int, default=1)
    p.set_defaults(run=_cmd_play)

    p = sub.add_parser("record", help="record the stream to an MJPEG file or a PNG sequence (Ctrl-C stops)")
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--mjpeg", help="output .mjpg file")
    target.add_argument("--png-dir", help="output folder for PNG frames")
    p.add_argument("--frames", type=int, default=100, help="frames to record (MJPEG: 0 = until interrupted)")
    p.add_argument("--fps", type=float, default=0, help="MJPEG rate cap")
    p.add_argument("--channel", help="record this channel (default: the first)")
    p.set_defaults(run=_cmd_record)

    p = sub.add_parser("effects", help="list, add, start, stop (fade), remove or change effects",
                       description="igclient effects list | add ID [type=smoke] [PATH=VALUE...] | start ID | "
                                   "stop ID | remove ID | set ID PATH=VALUE...")
    p.add_argument("action", nargs="?", default="list", choices=["list", "add", "start", "stop", "remove", "set"])
    p.add_argument("id", nargs="?")
    p.add_argument("fields", nargs="*", metavar="PATH=VALUE")
    p.set_defaults(run=_cmd_effects)

    p = sub.add_parser("bench", help="latency statistics: state sent -> frame received "
                                     "(the state and the IG clock are restored)")
    p.add_argument("--frames", type=int, default=200)
    p.add_argument("--modes", default="ws,http", help="ws, http or both")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.set_defaults(run=_cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except IGError as exc:
        print(f"igclient: rejected: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # bad assignment, scenario line, file type
        print(f"igclient: {exc}", file=sys.stderr)
        return 2
    except (httpx.TransportError, OSError) as exc:
        print(f"igclient: cannot reach {args.url}: {exc}" if isinstance(exc, httpx.TransportError)
              else f"igclient: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("igclient: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
