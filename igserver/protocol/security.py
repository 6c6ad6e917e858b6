"""The edge guard: what a request must show before any route sees it (docs/design.md#service: safe by default).

Threats, and the rule that stops each:
- A web page the operator opens POSTs to the IG (cross-site request forgery). Browsers send such "simple"
  requests without asking first only with form or text content types; so every write must say
  ``application/json`` or msgpack (415 otherwise: ``dependencies.message_body``, the one place bodies are
  read), which forces a CORS preflight the server never grants. And a write or WebSocket whose ``Origin`` is
  not the server's own (or configured) is refused here (403).
- DNS rebinding: a hostile name re-pointed at 127.0.0.1 makes the browser treat the IG as that site. The
  ``Host`` header then carries the hostile name: only loopback names, the bind address and configured names
  are served (403 otherwise).
- Anyone on the network: with a token set (required when bound beyond loopback), every request carries
  ``Authorization: Bearer <token>``, or the ``igserver_token`` cookie the viewer login sets
  (``GET /?access_token=<token>``: HttpOnly, SameSite=Strict, then a redirect that drops the token from the
  address bar), or, for players that cannot send headers (ffplay, VLC), ``?access_token=`` on a GET.
  Open without a token: ``/v1/health`` (liveness probes) and the API documentation.

A pure ASGI middleware, so the same rules cover HTTP and the WebSocket handshake.
"""

from __future__ import annotations

import hmac
import logging
from http.cookies import SimpleCookie
from urllib.parse import parse_qs, urlencode, urlsplit

from .codec import MSGPACK, PROBLEM_JSON, PROBLEM_MSGPACK, encode, negotiate
from .problems import ProblemError
from .settings import LOOPBACK_NAMES, WILDCARD_HOSTS, ServerSettings

log = logging.getLogger("igserver.protocol")

COOKIE = "igserver_token"
QUERY = "access_token"
SAFE = frozenset({"GET", "HEAD", "OPTIONS"})
OPEN_PATHS = ("/v1/health", "/docs", "/redoc", "/openapi.json", "/asyncapi.json", "/v1/ws-protocol",
              "/static-offline-docs/", "/v1/problems/", "/favicon.ico")


def _split_host(value: str) -> tuple[str, str | None]:
    """'example.com:8600' -> ('example.com', '8600'); '[::1]:80' -> ('::1', '80')."""
    value = value.strip().lower()
    if value.startswith("["):
        host, _, rest = value[1:].partition("]")
        return host, rest[1:] if rest.startswith(":") else None
    if value.count(":") == 1:
        host, port = value.split(":")
        return host, port
    return value, None


class EdgeGuard:
    """ASGI middleware enforcing Host, Origin and the bearer token."""

    def __init__(self, app, settings: ServerSettings):
        self.app = app
        self.token = settings.bearer_token()
        bound = settings.host.strip("[]").lower()
        hosts = set(LOOPBACK_NAMES) | {h.lower() for h in settings.allowed_hosts}
        if bound not in WILDCARD_HOSTS:
            hosts.add(bound)
        # Bound to a wildcard address with no names configured, the server cannot know its names; a token is
        # then required (serve() refuses to start without one), and a rebinding page cannot carry it.
        self.any_host = "*" in hosts or (bound in WILDCARD_HOSTS and not settings.allowed_hosts)
        self.hosts = frozenset(hosts)
        self.origins = frozenset(o.rstrip("/").lower() for o in settings.allowed_origins)

    # -- the rules, each returning a ProblemError or None
    def check_host(self, headers: dict[str, str]) -> ProblemError | None:
        if self.any_host:
            return None
        host, _ = _split_host(headers.get("host", ""))
        if host.endswith(".localhost") or host in self.hosts:
            return None
        return ProblemError("forbidden", f"Host {host!r} is not served here (add it to IGSERVER_ALLOWED_HOSTS)")

    def check_origin(self, headers: dict[str, str]) -> ProblemError | None:
        origin = headers.get("origin")
        if origin is None:
            # not from a browser script; browsers always send Origin on cross-site writes and WebSockets,
            # and Sec-Fetch-Site where they do not
            if headers.get("sec-fetch-site") == "cross-site":
                return ProblemError("forbidden", "cross-site request refused")
            return None
        origin = origin.rstrip("/").lower()
        if origin in self.origins:
            return None
        parts = urlsplit(origin)
        if parts.scheme in ("http", "https") and parts.netloc and parts.netloc == headers.get("host", "").lower():
            return None  # same origin: the viewer page
        return ProblemError("forbidden", f"Origin {origin!r} is not allowed (add it to IGSERVER_ALLOWED_ORIGINS)")

    def presented_token(self, scope, headers: dict[str, str]) -> str | None:
        """The token the request carries, stripped; a blank one (``?access_token=+++``) is none."""
        return (self._presented(scope, headers) or "").strip() or None

    def _presented(self, scope, headers: dict[str, str]) -> str | None:
        auth = headers.get("authorization", "")
        if auth[:7].lower() == "bearer ":
            return auth[7:].strip()
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("cookie", ""))
        except Exception:
            cookie = SimpleCookie()
        if COOKIE in cookie:
            return cookie[COOKIE].value
        if scope.get("method", "GET") in SAFE or scope["type"] == "websocket":
            values = parse_qs(scope.get("query_string", b"").decode("latin-1")).get(QUERY)
            if values:
                return values[0]
        return None

    def token_ok(self, presented: str | None) -> bool:
        return bool(presented) and hmac.compare_digest(presented.encode(), self.token.encode())

    def check(self, scope, headers: dict[str, str]) -> ProblemError | None:
        problem = self.check_host(headers)
        method = scope.get("method", "GET")
        if problem is None and (scope["type"] == "websocket" or method not in SAFE):
            problem = self.check_origin(headers)
        if problem is None and self.token and not scope["path"].startswith(OPEN_PATHS):
            if not self.token_ok(self.presented_token(scope, headers)):
                problem = ProblemError(
                    "unauthorized",
                    "send 'Authorization: Bearer <token>' (browsers: open /?access_token=<token> once)",
                    headers={"WWW-Authenticate": 'Bearer realm="igserver"'},
                )
        return problem

    # -- ASGI
    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        problem = self.check(scope, headers)
        if problem is None:
            if scope["type"] == "http" and self.token and scope["path"] == "/" and QUERY in parse_qs(
                    scope.get("query_string", b"").decode("latin-1")):
                return await self.login(scope, send, headers)
            return await self.app(scope, receive, send)
        log.warning("refused %s %s: %s", scope.get("method", "WS"), scope["path"], problem.detail)
        metrics = getattr(getattr(scope.get("app"), "state", None), "runtime", None)
        if metrics is not None:
            metrics.metrics.protocol_errors.inc(kind=problem.kind)
        if scope["type"] == "websocket":
            # before accept: uvicorn answers the handshake with HTTP 403
            await send({"type": "websocket.close", "code": 1008, "reason": problem.kind})
            return
        await self.send_problem(scope, send, headers, problem)

    async def login(self, scope, send, headers: dict[str, str]) -> None:
        """``GET /?access_token=T`` (already checked): set the cookie, redirect to the page without the token."""
        rest = {k: v for k, v in parse_qs(scope.get("query_string", b"").decode("latin-1")).items() if k != QUERY}
        location = "/" + (f"?{urlencode(rest, doseq=True)}" if rest else "")
        cookie = f"{COOKIE}={self.token}; Path=/; HttpOnly; SameSite=Strict"
        await send({"type": "http.response.start", "status": 303,
                    "headers": [(b"location", location.encode()), (b"set-cookie", cookie.encode()),
                                (b"cache-control", b"no-store"), (b"content-length", b"0")]})
        await send({"type": "http.response.body", "body": b""})

    @staticmethod
    async def send_problem(scope, send, headers: dict[str, str], problem: ProblemError) -> None:
        fmt = negotiate(headers.get("accept"), headers.get("content-type"))
        body = encode(problem.document(scope["path"]), fmt)
        media = PROBLEM_MSGPACK if fmt == MSGPACK else PROBLEM_JSON
        raw = [(b"content-type", media.encode()), (b"content-length", str(len(body)).encode())]
        raw += [(k.lower().encode(), v.encode()) for k, v in (problem.headers or {}).items()]
        await send({"type": "http.response.start", "status": problem.status, "headers": raw})
        await send({"type": "http.response.body", "body": body})
