"""Server settings: one pydantic-settings model, filled from CLI flags, ``IGSERVER_*`` variables and defaults.

Precedence: ``igserver serve --flag`` > environment (``IGSERVER_MAX_FPS=30``; nested limits as
``IGSERVER_LIMITS__MAX_BODY_BYTES``) > the defaults below. The settings table of docs/operations.md is this model
(``settings_table()`` writes it; a test keeps the two in step).
"""

from __future__ import annotations

import ipaddress
import json
from pathlib import Path
from typing import Annotated

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from ..assets.images import DEFAULT_MAX_PROFILE_PIXELS
from ..scene.model import TargetFps
from .codec import Limits

# Host names that always mean this machine. A browser can only reach a loopback-bound server under one of
# these, so any other Host header on a loopback server is a DNS-rebinding attempt.
CIGI = {"section": "cigi"}  # settings documented in docs/cigi.md, not in docs/operations.md's table
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1", "localhost.localdomain", "ip6-localhost"})
WILDCARD_HOSTS = frozenset({"0.0.0.0", "::", ""})


def is_loopback(host: str) -> bool:
    if host.lower() in LOOPBACK_NAMES or host.lower().endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class ServerSettings(BaseSettings):
    model_config = SettingsConfigDict(
        env_prefix="IGSERVER_", env_nested_delimiter="__", frozen=True, extra="ignore",
        cli_kebab_case=True, cli_implicit_flags=True,
    )

    host: str = Field("127.0.0.1", description="address to bind; a non-loopback one requires a token")
    port: int = Field(8600, ge=0, le=65535, description="TCP port")
    token: SecretStr | None = Field(
        None, description="bearer token every request must carry (except /v1/health and the docs)")
    token_file: Path | None = Field(None, description="read the token from this file (Docker/Kubernetes secrets)")
    allowed_hosts: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="Host header names served besides the loopback names and the bind address "
        "(DNS-rebinding guard); '*' serves any")
    allowed_origins: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="browser origins (scheme://host:port) allowed besides the server's own, for writes and WebSocket")
    max_fps: float = Field(60.0, gt=0, le=1000, description="stream render rate cap (frames/s)")
    target_fps: TargetFps = Field(
        0.0, description="frame rate the initial scene holds by trading detail for time (its quality.target_fps; "
        "render/overload.py); 0 = off, else 5-240")

    keepalive_s: float = Field(1.0, gt=0, le=60, description="a static scene is re-rendered and re-sent this often (s)")
    jpeg_quality: int = Field(85, ge=1, le=100, description="JPEG quality of streams")
    limits: Limits = Field(default_factory=Limits, description="message bounds (body bytes, depth, string, array, map)")
    ws_initial_credits: int = Field(2, ge=0, le=1024, description="frames a WebSocket client gets before its first ack")
    ws_max_credits: int = Field(16, ge=1, le=1024, description="most credits a WebSocket client may hold")
    timed_passes: bool = Field(True, description="time each render pass for /metrics, on one frame in 30")
    rehearse: bool = Field(
        True, description="before /v1/ready, draw the start scene unseen with a fire, every effect kind, lights, rain, "
        "snow, a rough and a calm sea and the eye under water, so their shader programs are compiled before a host "
        "asks for them (render/rehearsal.py); "
        "off: the first fire in a stream freezes it while they compile (0.15-1.5 s on llvmpipe)")
    animation_fps: float = Field(
        30.0, gt=0, le=1000, description="stream render rate while the IG clock runs (sim_time animates the scene); a scene's "
        "quality.target_fps above it sets the rate instead")
    render_timeout_s: float = Field(
        30.0, gt=0, le=3600,
        description="a render silent this long (s; no frame, no progress) is abandoned and its state falls back")
    watchdog_interval_s: float = Field(0.5, gt=0, le=60, description="how often the render process's liveness is checked (s)")
    max_raw_frame_bytes: int = Field(
        32 * 2**20, ge=0, description="raw (RGBA) frames above this are refused (413): ask for jpeg or png")
    # CIGI 3.3 over UDP (igserver/cigi, docs/cigi.md; its own settings table there)
    cigi: bool = Field(False, description="listen for a CIGI 3.3 host over UDP", json_schema_extra=CIGI)
    cigi_bind: str = Field("127.0.0.1", description="address the CIGI socket binds; a non-loopback one requires "
                           "--cigi-allow", json_schema_extra=CIGI)
    cigi_port: int = Field(8004, ge=0, le=65535, description="UDP port of host messages", json_schema_extra=CIGI)
    cigi_host_port: int = Field(8005, ge=1, le=65535, description="UDP port IG messages are sent to",
                                json_schema_extra=CIGI)
    cigi_host: str | None = Field(None, description="address IG messages are sent to; none = the sender of the "
                                  "last valid host message", json_schema_extra=CIGI)
    cigi_allow: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="host addresses allowed to send (others are dropped and counted); "
        "required when cigi_bind is not loopback", json_schema_extra=CIGI)
    cigi_sync: bool = Field(False, description="synchronous mode: the host's IG Control timestamps drive "
                            "sim_time (also whenever a host marks its timestamp valid)", json_schema_extra=CIGI)
    cigi_entity_types: Path | None = Field(None, description="TOML file mapping entity types to models and "
                                           "database numbers to scenes (none = the shipped default)",
                                           json_schema_extra=CIGI)
    idle_timeout_s: float = Field(
        10.0, gt=0, le=3600,
        description="a connection is closed when its request headers are not complete this long (s) after it "
        "opened or its last response ended, or when its request body stalls this long")
    max_connections: int = Field(
        512, ge=1, le=100_000,
        description="open connections (streams included) above which requests are answered 503")
    max_header_bytes: int = Field(16384, ge=1024, le=2**20, description="largest request head (line and headers)")
    max_ws_clients: int = Field(
        32, ge=0, le=10_000, description="WebSocket clients at once; one more is closed with code 1013 (try again later)")
    max_concurrent_queries: int = Field(
        4, ge=1, le=1024,
        description="water-height queries answered at once (REST and WebSocket); more are answered 503 with Retry-After")
    max_profile_pixels: int = Field(
        DEFAULT_MAX_PROFILE_PIXELS, ge=1, le=4096 * 4096,
        description="pixels of a profile image (width x height, read from its header): a larger one is refused (422)")

    @field_validator("allowed_hosts", "allowed_origins", "cigi_allow", mode="before")
    @classmethod
    def _comma_list(cls, value):
        # IGSERVER_ALLOWED_HOSTS=a.example,b.example as well as the JSON list pydantic-settings reads
        if isinstance(value, str):
            if value.lstrip().startswith("["):
                return json.loads(value)
            return [item.strip() for item in value.split(",") if item.strip()]
        return value

    def bearer_token(self) -> str | None:
        """The configured token (``token`` wins over ``token_file``); None when authentication is off.

        Surrounding whitespace is not part of a token (a header's value is read stripped), so a blank one
        (``IGSERVER_TOKEN='   '``) is no token: a network bind then refuses to start, as without one."""
        if self.token is not None and self.token.get_secret_value().strip():
            return self.token.get_secret_value().strip()
        if self.token_file is not None:
            text = self.token_file.read_text(encoding="utf-8").strip()
            return text or None
        return None

    @model_validator(mode="after")
    def _cigi_exposed(self) -> "ServerSettings":
        # CIGI has no authentication: beyond loopback only the listed hosts may drive the IG
        if self.cigi and not is_loopback(self.cigi_bind) and not self.cigi_allow:
            raise ValueError(f"cigi_bind {self.cigi_bind} is not loopback: list the host addresses allowed to "
                             "send in cigi_allow (--cigi-allow), CIGI has no authentication")
        return self

    def binds_beyond_loopback(self) -> bool:
        return not is_loopback(self.host)


def settings_table(section: str | None = None) -> str:
    """The settings table of docs/operations.md: variable, CLI flag, default, meaning
    (``section="cigi"``: the CIGI settings, whose table is docs/cigi.md's)."""
    rows = ["| environment variable | `igserver serve` flag | default | meaning |", "| --- | --- | --- | --- |"]
    for name, field in ServerSettings.model_fields.items():
        if (field.json_schema_extra or {}).get("section") != section:
            continue
        default = field.get_default(call_default_factory=True)
        if isinstance(default, Limits):  # one row per nested bound: IGSERVER_LIMITS__MAX_DEPTH, --limits.max-depth
            for key, value in default.model_dump().items():
                meaning = Limits.model_fields[key].description
                rows.append(f"| `IGSERVER_LIMITS__{key.upper()}` | `--limits.{key.replace('_', '-')}` | `{value}` "
                            f"| message bound: {meaning} |")
            continue
        shown = "—" if default in (None, []) else f"`{default}`"
        rows.append(f"| `IGSERVER_{name.upper()}` | `--{name.replace('_', '-')}` | {shown} | {field.description} |")
    return "\n".join(rows)
