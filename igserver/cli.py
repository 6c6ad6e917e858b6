"""Command line: ``igserver serve | cluster | health | render | bench | quality``."""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from pydantic import ValidationError

from .scene.model import PRESET_NAMES as PRESET_CHOICES


def resolutions(text: str) -> list[tuple[int, int]]:
    """``--resolutions 640x360,1280x720`` (an argparse type: a typo is a usage message)."""
    sizes = []
    for item in text.split(","):
        w, x, h = item.strip().lower().partition("x")
        if not (x and w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
            raise argparse.ArgumentTypeError(
                f"expected WIDTHxHEIGHT[,WIDTHxHEIGHT...] in pixels, e.g. 640x360,1280x720; got {item.strip()!r}")
        sizes.append((int(w), int(h)))
    return sizes


def study_names() -> list[str]:
    """The studies in igserver/quality: its modules with a ``run`` (read from the source: importing every
    study to list them would load the renderer)."""
    import re
    from importlib import resources

    return sorted(entry.name[:-3] for entry in resources.files("igserver.quality").iterdir()
                  if entry.name.endswith(".py") and entry.name != "report.py"
                  and re.search(r"^def run\(", entry.read_text(encoding="utf-8"), re.MULTILINE))


def _scene_from_args(args):
    from .scene import apply_patch, load_scene, patch_from_assignments

    scene = load_scene(args.scene)
    patch = patch_from_assignments(args.set or [], base=scene.model_dump(mode="json"))
    camera = {k: v for k, v in (("width", args.width), ("height", args.height)) if v is not None}
    if camera:
        patch.setdefault("camera", {}).update(camera)
    if getattr(args, "preset", None):
        patch.setdefault("quality", {})["preset"] = args.preset
    return apply_patch(scene, patch)


def cmd_source_id(args) -> int:
    from .source_id import source_id

    print(source_id())
    return 0


def cmd_render(args) -> int:
    from PIL import Image

    from .render.worker import RenderError, RenderService
    from .source_id import source_id

    scene = _scene_from_args(args)
    try:
        with RenderService(scene) as service:
            frame = service.render(timed=True)
    except RenderError as exc:
        # no EGL, no GL 4.5, a driver crash: say what to install, not where in our code it happened
        print(f"igserver render: {str(exc).strip().splitlines()[-1]}", file=sys.stderr)
        return 1
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(frame.rgba[:, :, :3]).save(args.out)
    source = source_id()  # which code made the picture (source_id.py): pictures from two machines compare
    if getattr(args, "json", False):
        import json

        print(json.dumps({"out": str(args.out), "width": frame.width, "height": frame.height, "passes": frame.passes,
                          "render_ms": round(frame.render_ms, 3), "ev100": round(frame.ev100, 3),
                          "source": source,
                          "illuminance_lux": float(f"{frame.illuminance_lux:.6g}")}))
        return 0
    print(f"wrote {args.out} ({frame.width}x{frame.height}, passes {' '.join(frame.passes)}, "
          f"source {source}, "
          f"{frame.render_ms:.1f} ms, EV100 {frame.ev100:.2f}, {frame.illuminance_lux:.4g} lx)")
    return 0


def cmd_bench(args) -> int:
    from . import bench

    if args.channels:
        from .bench_channels import run_channels

        scenes = args.scenes.split(",") if args.scenes else ["demo"]
        run_channels(scenes, args.resolutions, args.frames, args.set or [], args.channels, args.json)
        return 0
    scenes = args.scenes.split(",") if args.scenes else bench.DEFAULT_SCENES
    presets = args.presets.split(",") if args.presets else ([args.preset] if args.preset else None)
    bench.run(scenes, args.resolutions, args.frames, args.set or [], args.json, presets, args.markdown)
    return 0


def cmd_serve(args) -> int:
    from .protocol.app import serve
    from .protocol.settings import ServerSettings

    # flags > IGSERVER_* environment > defaults (pydantic-settings merges them)
    settings = ServerSettings(_cli_settings_source=args.settings_source(parsed_args=args))
    return serve(scene_path=args.scene or None, width=args.width, height=args.height, settings=settings,
                 preset=args.preset)


def cmd_cluster(args) -> int:
    from .cluster.cli import run

    return run(args.config, check=args.check)


def cmd_health(args) -> int:
    """Container health check: is the local server ready (a frame can be served)? Reads the IGSERVER_* settings."""
    import httpx

    from .protocol.settings import WILDCARD_HOSTS, ServerSettings

    settings = ServerSettings()
    host = "127.0.0.1" if settings.host in WILDCARD_HOSTS else settings.host
    host = f"[{host}]" if ":" in host else host
    token = settings.bearer_token()
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    path = "/v1/health" if args.live else "/v1/ready"
    try:
        response = httpx.get(f"http://{host}:{settings.port}{path}", headers=headers, timeout=args.timeout)
    except httpx.HTTPError as exc:
        print(f"igserver health: {exc}", file=sys.stderr)
        return 1
    print(response.text)
    return 0 if response.status_code == 200 else 1


def add_serve_arguments(parser: argparse.ArgumentParser, default_scene: str | None) -> None:
    """``igserver serve``'s flags: the scene and size, and one flag per server setting (settings.py)."""
    from pydantic_settings import CliSettingsSource

    from .protocol.settings import ServerSettings

    parser.add_argument("--scene", default=default_scene,
                        help=f"scene file or name in igserver/scenes/ (default {default_scene or 'built-in'})")
    parser.add_argument("--width", type=int)
    parser.add_argument("--height", type=int)
    parser.add_argument("--preset", choices=PRESET_CHOICES, help="quality preset of the initial scene")
    parser.set_defaults(settings_source=CliSettingsSource(ServerSettings, root_parser=parser))


def cmd_quality(args) -> int:
    # checked by name first: a study that fails to import (a missing extra) must not read as "no such study"
    names = study_names()
    if args.pipeline not in names:
        print(f"no quality study named {args.pipeline!r}; studies: {', '.join(names)} "
              "(or none: all of them into one report)", file=sys.stderr)
        return 2
    module = importlib.import_module(f"igserver.quality.{args.pipeline}")
    return module.run(args.rest) or 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="igserver", description="Network image generator for training simulators")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("serve", help="start the IG service (REST, WebSocket, MJPEG, viewer page)",
                       description="Every setting is also an IGSERVER_* environment variable (docs/operations.md: Settings).")
    add_serve_arguments(p, "demo")
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("cluster", help="the service with its channels rendered by Ray actors, one GPU each "
                                       "(docs/cluster.md; needs igserver[cluster])")
    p.add_argument("--config", required=True, help="cluster configuration (TOML): scene, channels, workers, Ray")
    p.add_argument("--check", action="store_true", help="check the configuration and print the plan; start nothing")
    p.set_defaults(func=cmd_cluster)

    p = sub.add_parser("health", help="exit 0 when the local server is ready (Docker HEALTHCHECK)")
    p.add_argument("--live", action="store_true", help="only check that the server process answers")
    p.add_argument("--timeout", type=float, default=4.0)
    p.set_defaults(func=cmd_health)

    p = sub.add_parser("render", help="render one frame of a scene to a PNG")
    p.add_argument("--scene", required=True, help="scene file or name in igserver/scenes/")
    p.add_argument("--out", required=True, help="PNG path")
    p.add_argument("--width", type=int)
    p.add_argument("--height", type=int)
    p.add_argument("--set", action="append", metavar="PATH=VALUE", help="override a field, e.g. camera.pitch=10")
    p.add_argument("--json", action="store_true", help="print the frame's read-out (EV100, illuminance) as JSON")
    p.add_argument("--preset", choices=PRESET_CHOICES, help="quality preset (= --set quality.preset=...)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("source-id", help="digest of this tree's package files, as printed with pictures and "
                                         "stored in benchmark reports (igserver/source_id.py)")
    p.set_defaults(func=cmd_source_id)

    p = sub.add_parser("bench", help="frame time per pass and in total")
    p.add_argument("--scenes", help="comma-separated scene names (default: all example scenes)")
    p.add_argument("--resolutions", type=resolutions, default="640x360", metavar="WxH[,WxH...]",
                   help="frame sizes, e.g. 640x360,1280x720")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--json", help="also write the report as JSON")
    p.add_argument("--markdown", help="also write the performance table (the README's form) to this file")
    p.add_argument("--presets", help="comma-separated quality presets, one run each (e.g. low,medium,high)")
    p.add_argument("--preset", choices=PRESET_CHOICES, help="one quality preset (default: the scene's)")
    p.add_argument("--set", action="append", metavar="PATH=VALUE")
    p.add_argument("--channels", type=int, choices=range(1, 17), metavar="N",
                   help="N channels of one state against one channel (the cost ratio; default scene demo, "
                        "each channel of --resolutions)")
    p.add_argument("--service", action="store_true",
                   help="end-to-end latency through the real server (flags: --frames --width --height --modes --json)")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("quality", help="error against run time: one pipeline's study, or all of them into "
                                       "one report (no argument; --quick, --out out/quality)")
    p.add_argument("pipeline", nargs="?", help="a study in igserver/quality (sky, volumes, ...); none = all")
    p.add_argument("rest", nargs=argparse.REMAINDER)
    p.set_defaults(func=cmd_quality)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"] and "--service" in argv:
        # End-to-end latency through the real server: its own flags (--frames --width --modes ...).
        from .protocol.bench import run_service_bench

        return run_service_bench([a for a in argv[1:] if a != "--service"]) or 0
    if argv[:1] == ["quality"] and (len(argv) == 1 or argv[1].startswith("-")) and "-h" not in argv[1:2]:
        # No study named: every study into one report (its own flags: --quick --out --only).
        from .quality.report import run_all

        return run_all(argv[1:])
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValidationError as exc:
        for err in exc.errors():
            print(f"invalid {'.'.join(str(p) for p in err['loc'])}: {err['msg']}", file=sys.stderr)
        return 2
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
