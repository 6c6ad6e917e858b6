"""The cluster's configuration file (TOML, docs/cluster.md) and which worker renders which channel.

Pure model code: no Ray, no GL (the CLI checks a file before anything starts).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..scene.channels import MAX_CHANNELS, Channel
from ..scene.model import Scene

MAX_WORKERS = 64


class WorkerConfig(BaseModel):
    """One worker's channels by id (rendered together, sharing its world work)."""

    model_config = ConfigDict(extra="forbid")
    channels: list[str] = Field(..., min_length=1, max_length=MAX_CHANNELS)


class ClusterConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    scene: str = Field("demo", description="scene file (TOML) or a name in igserver/scenes/")
    address: str = Field("local", min_length=1, description="Ray: 'local' starts an instance here, 'auto' joins the "
                         "one `ray start` runs on this machine, else a Ray address (host:6379, ray://host:10001)")
    workers: int | None = Field(None, ge=1, le=MAX_WORKERS,
                                description="channel workers (Ray actors); default: one per [[worker]], else 2")
    gpus: Literal["auto"] | bool = Field("auto", description="one GPU per worker: 'auto' when the cluster has GPUs")
    cpus_per_worker: int = Field(1, ge=1, le=256, description="Ray num_cpus of a worker; LP_NUM_THREADS on llvmpipe")
    barrier_timeout_ms: float = Field(1000.0, gt=0.0, le=600_000.0,
                                      description="ms a frame waits for its slowest worker before it goes without it")
    max_restarts: int = Field(-1, ge=-1, le=1_000_000, description="Ray max_restarts of a worker (-1: always)")
    start_timeout_s: float = Field(300.0, gt=0.0, le=3600.0, description="s for every worker to come up")
    server: dict = Field(default_factory=dict, description="igserver serve's settings (host, port, token_file, cigi...)")
    channels: list[Channel] = Field(default_factory=list, max_length=MAX_CHANNELS,
                                    description="the scene's channels (replacing the scene file's when given)")
    worker: list[WorkerConfig] = Field(default_factory=list, max_length=MAX_WORKERS,
                                       description="each worker's channels; channels not listed are spread")

    @model_validator(mode="after")
    def _consistent(self) -> "ClusterConfig":
        if self.workers is None:
            self.workers = len(self.worker) or 2
        if len(self.worker) > self.workers:
            raise ValueError(f"worker: {len(self.worker)} [[worker]] tables for workers = {self.workers}")
        seen: dict[str, int] = {}
        for i, w in enumerate(self.worker):
            for cid in w.channels:
                if cid in seen:
                    raise ValueError(f"worker.{i}.channels: channel {cid!r} is already worker {seen[cid]}'s")
                seen[cid] = i
        ids = {c.id for c in self.channels}
        unknown = sorted(set(seen) - ids) if self.channels else []
        if unknown:
            raise ValueError(f"worker: channels {unknown} are not in channels ({sorted(ids)})")
        return self

    def start_scene(self) -> Scene:
        """The scene file with the configured channels (validated as any state: ids, budget)."""
        from ..scene.files import load_scene

        scene = load_scene(self.scene)
        if self.channels:
            data = scene.model_dump(mode="python")
            data["channels"] = [c.model_dump(mode="python") for c in self.channels]
            scene = Scene.model_validate(data)
        return scene


class ConfigError(ValueError):
    """A configuration file that cannot be used; the message names the key."""


def load_config(path: str | Path) -> ClusterConfig:
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror or exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not TOML: {exc}") from exc
    try:
        return ClusterConfig.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(file)"
        raise ConfigError(f"{path}: {where}: {first['msg']}") from exc


def assign(ids: list[str], config: ClusterConfig, dead: frozenset[int] = frozenset()) -> list[list[str]]:
    """Channel ids per worker: the ids a [[worker]] lists go to it (in the state's order), the others one by
    one to the live worker with the fewest channels (the lowest index on a tie). A state without channels is
    the implicit channel ``""``: the first live worker renders it. ``dead``: workers Ray will not restart;
    their channels are spread over the others. Ids a [[worker]] lists that the state has not are skipped."""
    workers = config.workers or 1
    out: list[list[str]] = [[] for _ in range(workers)]
    live = [out[i] for i in range(workers) if i not in dead]
    if not live:
        return out
    owner = {cid: i for i, w in enumerate(config.worker) for cid in w.channels if i not in dead}
    for cid in ids:
        if cid in owner:
            out[owner[cid]].append(cid)
    for cid in ids:
        if cid not in owner:
            min(live, key=len).append(cid)
    order = {cid: i for i, cid in enumerate(ids)}
    return [sorted(part, key=order.__getitem__) for part in out]
