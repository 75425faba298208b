"""Who may talk to the workbench: an Origin check and a per-run secret token.

viser 1.1.1 starts its websocket server with no Origin check, so any web page open in a
browser on this machine could connect to the workbench and drive it. Here every request
is checked before viser sees it (the ``process_request`` hook of the ``websockets``
server viser starts):

- The page (``/`` or ``/index.html``) needs the token, from the URL the server prints
  (``?token=...``, as Jupyter does) or from the cookie set when that URL was opened.
  The cookie is HttpOnly and SameSite=Strict, so a page of another site never sends it.
- The websocket handshake needs an Origin that is the workbench's own (or no Origin at
  all: not a browser) and the token (the cookie, ``?token=`` or an
  ``Authorization: token ...`` header). viser's page opens its websocket without the
  page's query string, so in a browser the cookie carries the token.
- With ``token=None`` (``--no-token``, trusted networks) the Origin check stays; on a
  loopback bind the Host header must also name this machine (no DNS rebinding).

The static files of viser's client (scripts, styles) hold no session data and are
served to anyone.
"""

from __future__ import annotations

import hmac
import http
import logging
import secrets
import threading
from urllib.parse import parse_qs, urlsplit

import websockets.asyncio.server as _ws_server
from websockets.datastructures import Headers
from websockets.http11 import Response

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]", "::1")
_PAGE_PATHS = ("/", "/index.html")

_install_lock = threading.Lock()
_construct_lock = threading.Lock()
_current_guard: list = [None]  # the guard of the server being constructed (under _construct_lock)


def new_token() -> str:
    return secrets.token_urlsafe(24)


class ConnectionGuard:
    """The checks for one workbench. ``port`` is set once the server is bound."""

    def __init__(self, token: str | None, bind_host: str):
        self.token = token
        self.bind_host = bind_host
        self.port: int | None = None
        self.refused = 0  # requests refused (tests, logs)

    # ---- the checks ------------------------------------------------------------
    @property
    def cookie_name(self) -> str:
        return f"sonarcal_token_{self.port}"  # cookies ignore the port: one per workbench

    def _token_ok(self, request) -> bool:
        if self.token is None:
            return True
        given = []
        query = parse_qs(urlsplit(request.path).query)
        given += query.get("token", [])
        for auth in request.headers.get_all("Authorization"):
            if auth.lower().startswith("token "):
                given.append(auth[6:].strip())
        for header in request.headers.get_all("Cookie"):
            for part in header.split(";"):
                name, _, value = part.strip().partition("=")
                if name == self.cookie_name:
                    given.append(value)
        return any(hmac.compare_digest(g.encode(), self.token.encode()) for g in given)

    def _host_ok(self, request) -> bool:
        hosts = request.headers.get_all("Host")
        if len(hosts) != 1:
            return False
        host = hosts[0]
        if self.token is not None or self.bind_host not in LOOPBACK_NAMES:
            return True  # the token (or the operator's choice of an open network) decides
        name, _, port = host.rpartition(":") if not host.endswith("]") else (host, "", "")
        return name in LOOPBACK_NAMES and port == str(self.port)

    def _origin_ok(self, request) -> bool:
        origins = request.headers.get_all("Origin")
        if not origins:
            return True  # not a browser (browsers always send Origin on a websocket handshake)
        if len(origins) != 1:
            return False
        origin, host = origins[0], request.headers.get_all("Host")[0]
        return origin.lower() in (f"http://{host}".lower(), f"https://{host}".lower())

    def check(self, request) -> Response | None:
        """None to let viser handle the request, or the refusal to send instead."""
        try:
            return self._check(request)
        except Exception:  # a malformed request: refused, never a 500 or a traceback
            return self._refuse(http.HTTPStatus.BAD_REQUEST, "malformed request")

    def _check(self, request) -> Response | None:
        is_ws = any(v.lower() == "websocket" for v in request.headers.get_all("Upgrade"))
        path = urlsplit(request.path).path
        if not self._host_ok(request):
            return self._refuse(http.HTTPStatus.FORBIDDEN, "unknown Host")
        if is_ws:
            if not self._origin_ok(request):
                return self._refuse(http.HTTPStatus.FORBIDDEN, "cross-origin websocket refused")
            if not self._token_ok(request):
                return self._refuse(http.HTTPStatus.FORBIDDEN, "websocket without the workbench token")
            return None
        if path in _PAGE_PATHS and not self._token_ok(request):
            return self._refuse(http.HTTPStatus.FORBIDDEN,
                                "open the full URL the server printed (it holds the access token)")
        return None

    def _refuse(self, status, text: str) -> Response:
        self.refused += 1
        body = f"sonarcal workbench: {text}\n".encode()
        return Response(status, status.phrase, Headers({"Content-Type": "text/plain; charset=utf-8",
                                                        "Content-Length": str(len(body))}), body)

    def decorate(self, request, response: Response | None) -> Response | None:
        """Set the token cookie on the page (HttpOnly, SameSite=Strict) and forbid framing."""
        if response is None or self.token is None:
            return response
        if urlsplit(request.path).path in _PAGE_PATHS and response.status_code == 200:
            response.headers["Set-Cookie"] = (f"{self.cookie_name}={self.token}; Path=/; HttpOnly; "
                                              "SameSite=Strict")
        response.headers["X-Frame-Options"] = "DENY"
        response.headers["Content-Security-Policy"] = "frame-ancestors 'none'"
        response.headers["Cache-Control"] = "no-store"
        return response


# ---- hooking into viser's server --------------------------------------------------
def _wrap_process_request(guard: ConnectionGuard, inner):
    def process_request(connection, request):
        refusal = guard.check(request)
        if refusal is not None:
            return refusal
        response = inner(connection, request) if inner is not None else None
        return guard.decorate(request, response)

    return process_request


def _guarded_serve(original):
    def serve(*args, **kwargs):
        guard = _current_guard[0]
        if guard is not None:
            kwargs["process_request"] = _wrap_process_request(guard, kwargs.get("process_request"))
        return original(*args, **kwargs)

    serve.__wrapped__ = original
    return serve


def install() -> None:
    """Wrap ``websockets.asyncio.server.serve`` once (viser looks it up at each start)."""
    with _install_lock:
        if not getattr(_ws_server.serve, "_sonarcal_guard", False):
            wrapped = _guarded_serve(_ws_server.serve)
            wrapped._sonarcal_guard = True
            _ws_server.serve = wrapped
    quiet_handshake_noise()


def start_guarded(guard: ConnectionGuard, make_server):
    """Call ``make_server()`` (which starts a viser server) with ``guard`` on its requests."""
    install()
    with _construct_lock:
        _current_guard[0] = guard
        try:
            return make_server()
        finally:
            _current_guard[0] = None


class _NoHandshakeNoise(logging.Filter):
    """Drop the tracebacks ``websockets`` logs for a bare TCP connect or a port scan."""

    def filter(self, record):
        msg = record.getMessage()
        if msg.startswith(("opening handshake failed", "connection rejected")):
            record.exc_info = None
            record.exc_text = None
            return False
        return True


def quiet_handshake_noise() -> None:
    for name in ("websockets.server", "websockets"):
        logger = logging.getLogger(name)
        if not any(isinstance(f, _NoHandshakeNoise) for f in logger.filters):
            logger.addFilter(_NoHandshakeNoise())
