"""``igserver cluster --config FILE``: the front server with its channels rendered by Ray actors."""

from __future__ import annotations

import importlib.util
import sys

from pydantic import ValidationError

from .config import ConfigError, assign, load_config


def plan(config, scene) -> list[str]:
    """What the cluster will run, one line per worker (``--check`` prints it)."""
    ids = [c.id for c in scene.channels] or [""]
    lines = [f"ray: {config.address}; gpus: {config.gpus}; barrier: {config.barrier_timeout_ms:g} ms; "
             f"max_restarts: {config.max_restarts}"]
    sizes = {c.id: f"{c.width}x{c.height}" for c in scene.channels} or {"": f"{scene.camera.width}x{scene.camera.height}"}
    for i, part in enumerate(assign(ids, config)):
        shown = ", ".join(f"{cid or '(camera)'} {sizes[cid]}" for cid in part) or "(idle)"
        lines.append(f"worker {i}: {shown}")
    return lines


def run(config_path: str, check: bool = False) -> int:
    try:
        config = load_config(config_path)
        scene = config.start_scene()
        from ..protocol.settings import ServerSettings

        settings = ServerSettings(**config.server)
    except ConfigError as exc:
        print(f"igserver cluster: {exc}", file=sys.stderr)
        return 2
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        print(f"igserver cluster: {config_path}: {where}: {first['msg']}", file=sys.stderr)
        return 2
    except (FileNotFoundError, ValueError) as exc:
        print(f"igserver cluster: {config_path}: {exc}", file=sys.stderr)
        return 2
    for line in plan(config, scene):
        print(f"igserver cluster: {line}", flush=True)
    if check:
        return 0
    if importlib.util.find_spec("ray") is None:
        print("igserver cluster: Ray is not installed: pip install 'igserver[cluster]'", file=sys.stderr)
        return 2
    from ..protocol.app import serve
    from .service import ClusterService

    return serve(scene=scene, settings=settings, service=ClusterService(config, scene))
