"""The live view's HTTP and WebSocket server: a Starlette application served by uvicorn in a thread beside
the run (docs/live.md lists the API).

Security: the server binds 127.0.0.1 unless told another interface; then a random token is required on
every request and on the WebSocket (``?token=`` or ``Authorization: Bearer``), compared in constant time,
else 403.  Bound to the loopback interface, a request must name it in its ``Host`` (a page of another site
that resolves its own name to 127.0.0.1 is refused).  No cross-origin access: no CORS header is ever sent,
and a request whose ``Origin`` is not the server's own is refused (a page of another site cannot drive the
run nor read its stream).
"""
from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
import math
import os
import socket
import threading
import time
from importlib import resources
from typing import Any, Awaitable, Callable, Protocol

from starlette.applications import Starlette
from starlette.requests import HTTPConnection, Request
from starlette.responses import HTMLResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from .session import Refused

#: The files of the page beside index.html (static/; served at /static/NAME): its script, the chart library
#: (uPlot, MIT licence, vendored with its licence) and its style sheet.  Nothing comes from another host.
ASSETS = {"live.js": "text/javascript", "uPlot.iife.min.js": "text/javascript", "uPlot.min.css": "text/css",
          "uPlot.LICENSE": "text/plain"}

#: What the page may load: its own files only (its script and styles; the API and the stream on its host).
CSP = ("default-src 'none'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
       "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")


class Source(Protocol):
    """What the server serves: a live run (:class:`.session.LiveSession`) or a finished one
    (:class:`.finished.FinishedRun`)."""

    def state(self) -> dict[str, Any]: ...

    def submit(self, kind: str, **args: Any) -> Any: ...

    def subscribe(self, sink: Callable[[dict[str, Any] | None], None]) -> Callable[[], None]: ...

    def header(self) -> dict[str, Any]: ...


def clean(obj: Any) -> Any:
    """``obj`` with every non-finite float as None (JSON has no NaN nor infinities)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    return obj


def _json(obj: Any, status: int = 200) -> Response:
    return Response(json.dumps(clean(obj), default=str), status, media_type="application/json")


def _error(reason: str, status: int) -> Response:
    return _json({"error": reason}, status)


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) is the loopback interface."""
    if host == "localhost":
        return True
    return ipaddress.ip_address(host).is_loopback


class Guard:
    """Who may use the server: the token (where one is required), the ``Host`` a loopback server answers to,
    the ``Origin`` a browser's request comes from."""

    def __init__(self, host: str, port: int, token: str | None) -> None:
        self.token = token
        self.hosts: set[str] | None = None
        if is_loopback(host):
            self.hosts = {f"{h}:{port}" for h in ("127.0.0.1", "localhost", "[::1]")}

    def refusal(self, conn: HTTPConnection, token: bool = True) -> str | None:
        """Why the request is refused (403), or None (``token``: the request needs the token, where one is
        required)."""
        if self.token is not None and token:
            given = conn.query_params.get("token")
            auth = conn.headers.get("authorization", "")
            if given is None and auth.lower().startswith("bearer "):
                given = auth[7:].strip()
            if given is None or not hmac.compare_digest(given.encode(), self.token.encode()):
                return "a token is required (the one in the address the run printed)"
        host = conn.headers.get("host", "")
        if self.hosts is not None and host not in self.hosts:
            return f"host {host!r} is not this server's"
        origin = conn.headers.get("origin")
        if origin is not None and origin != f"http://{host}":
            return f"cross-origin requests are refused (origin {origin!r})"
        return None


def make_app(session: Source, guard: Guard) -> Starlette:
    """The application: the page (and its files), the state, the commands, the stream of rows."""
    api = _Api(session, guard)
    return Starlette(routes=[
        Route("/", api.guarded(api.page)),
        Route("/static/{name}", api.asset),
        Route("/api/state", api.guarded(api.state)),
        Route("/api/pause", api.command("pause", no_args), methods=["POST"]),
        Route("/api/resume", api.command("resume", no_args), methods=["POST"]),
        Route("/api/stop", api.command("stop", no_args), methods=["POST"]),
        Route("/api/step", api.command("step", step_args), methods=["POST"]),
        Route("/api/rate", api.command("rate", rate_args), methods=["POST"]),
        Route("/api/set", api.command("set", set_args), methods=["POST"]),
        WebSocketRoute("/api/stream", api.stream),
    ])


Handler = Callable[[Request], Awaitable[Response]]


class _Api:
    """The handlers of :func:`make_app` over one session."""

    def __init__(self, session: Source, guard: Guard) -> None:
        self.session, self.guard = session, guard

    def guarded(self, fn: Handler) -> Handler:
        """``fn`` behind the guard (403 with the reason)."""
        async def handler(request: Request) -> Response:
            why = self.guard.refusal(request)
            if why is not None:
                return _error(why, 403)
            return await fn(request)
        return handler

    async def page(self, request: Request) -> Response:
        html = resources.files(__package__).joinpath("static", "index.html").read_text(encoding="utf-8")
        return HTMLResponse(html, headers={"Content-Security-Policy": CSP, "X-Frame-Options": "DENY",
                                           "Cache-Control": "no-store"})

    async def asset(self, request: Request) -> Response:
        """A file of the page (the same for every run, no token needed: it holds nothing of the run); the
        Host and Origin checks still apply."""
        name = request.path_params["name"]
        why = self.guard.refusal(request, token=False)
        if why is not None:
            return _error(why, 403)
        if name not in ASSETS:
            return _error(f"no file {name!r}", 404)
        data = resources.files(__package__).joinpath("static", name).read_bytes()
        return Response(data, media_type=ASSETS[name], headers={"Cache-Control": "max-age=3600",
                                                                "X-Content-Type-Options": "nosniff"})

    async def state(self, request: Request) -> Response:
        return _json(self.session.state())

    def command(self, kind: str, check: Callable[[dict[str, Any]], dict[str, Any]]) -> Handler:
        """The handler of a command: its body checked (400), queued, answered with the state after it."""
        async def handler(request: Request) -> Response:
            try:
                args = check(await _body(request))
                result = await asyncio.wrap_future(self.session.submit(kind, **args))
            except Refused as exc:
                return _error(exc.reason, exc.status)
            return _json(result)
        return self.guarded(handler)

    async def stream(self, ws: WebSocket) -> None:
        """The rows as the run goes: the columns first, then each row, then the end (see docs/live.md)."""
        why = self.guard.refusal(ws)
        if why is not None:
            await ws.close(code=1008, reason=why)   # (before the handshake: answered 403)
            return
        await ws.accept()
        rows, sink = _client_queue(asyncio.get_running_loop())
        await ws.send_text(json.dumps(clean({**self.session.header(), "state": self.session.state()}), default=str))
        unsubscribe = self.session.subscribe(sink)
        try:
            while True:
                msg = await rows.get()
                if msg is None:
                    await ws.send_text(json.dumps(clean({"type": "end", "state": self.session.state()}), default=str))
                    await ws.close()
                    break
                await ws.send_text(json.dumps(msg if len(msg) == 2 else clean(msg), default=str))
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            unsubscribe()


def _client_queue(loop: asyncio.AbstractEventLoop
                  ) -> tuple[asyncio.Queue[dict[str, Any] | None], Callable[[dict[str, Any] | None], None]]:
    """A client's queue of rows on the server's loop, and the sink the stepping thread hands them to (a
    client that does not keep up misses rows: the run never waits for it)."""
    rows: asyncio.Queue[dict[str, Any] | None] = asyncio.Queue(maxsize=200)

    def put(msg: dict[str, Any] | None) -> None:
        if not rows.full():
            rows.put_nowait(msg)
        elif msg is None:   # the end always arrives: a row dropped for it
            rows.get_nowait()
            rows.put_nowait(msg)

    def sink(msg: dict[str, Any] | None) -> None:   # (the stepping thread)
        try:
            loop.call_soon_threadsafe(put, msg)
        except RuntimeError:   # the server's loop has closed
            pass
    return rows, sink


async def _body(request: Request) -> dict[str, Any]:
    """The JSON object of a command's body ({} for none); Refused otherwise."""
    raw = await request.body()
    if not raw.strip():
        return {}
    try:
        doc = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        raise Refused("the body is not JSON") from None
    if not isinstance(doc, dict):
        raise Refused("the body must be a JSON object")
    return doc


def no_args(doc: dict[str, Any]) -> dict[str, Any]:
    if doc:
        raise Refused(f"takes no arguments (got {', '.join(map(repr, doc))})")
    return {}


def _only(doc: dict[str, Any], *keys: str) -> None:
    extra = [k for k in doc if k not in keys]
    if extra:
        raise Refused(f"unknown key {extra[0]!r} (the keys: {', '.join(keys)})")


def step_args(doc: dict[str, Any]) -> dict[str, Any]:
    """{"steps": N}: N communication steps, an integer >= 1 (default 1)."""
    _only(doc, "steps")
    n = doc.get("steps", 1)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise Refused(f"steps {n!r}: a whole number of steps >= 1")
    return {"steps": n}


def rate_args(doc: dict[str, Any]) -> dict[str, Any]:
    """{"factor": F}: F x real time, F > 0 and finite, or 0 for as fast as possible."""
    _only(doc, "factor")
    f = doc.get("factor")
    if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or f < 0:
        raise Refused(f"factor {f!r}: a factor of real time (a number > 0), or 0 for as fast as possible")
    return {"factor": float(f)}


def set_args(doc: dict[str, Any]) -> dict[str, Any]:
    """{"variable": "instance.name", "value": V}."""
    _only(doc, "variable", "value")
    ref = doc.get("variable")
    if not isinstance(ref, str) or not ref:
        raise Refused("variable: the name of a variable, \"instance.name\"")
    if "value" not in doc or isinstance(doc["value"], (dict, list)) or doc["value"] is None:
        raise Refused(f"{ref}: a value (a number, a boolean or a string) is missing")
    return {"variable": ref, "value": doc["value"]}


class LiveServer:
    """The server of a live session on ``host``:``port`` (0: a free port), its socket bound at once
    (:class:`OSError` where it cannot be: the port in use), served in a thread from :meth:`start` to
    :meth:`close`."""

    def __init__(self, host: str, port: int, token: str | None) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        if os.name != "nt":   # a port whose last server has just ended (its connections in TIME_WAIT) binds again;
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)   # one another server listens on does not
        try:
            sock.bind((host, port))
            sock.listen(16)
        except OSError:
            sock.close()
            raise
        self.sock = sock
        self.host, self.port, self.token = host, int(sock.getsockname()[1]), token
        self.guard = Guard(host, self.port, token)
        self._server: Any = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The page's address (with the token where one is required)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def start(self, session: Source) -> None:
        """Serve ``session`` in a thread; returns once the server has started (its start-up, a few tens of
        milliseconds of imports and set-up, then does not compete with the run's first steps)."""
        import uvicorn

        config = uvicorn.Config(make_app(session, self.guard), log_level="warning", access_log=False,
                                lifespan="off", ws="websockets-sansio", timeout_graceful_shutdown=2)
        self._server = _server_class()(config)
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [self.sock]},
                                        name="wmr-cosim live view", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self._server.started and self._thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.002)

    def close(self) -> None:
        """Stop serving (the clients' connections closed) and wait for the thread; the socket closed."""
        if self._thread is not None and self._server is not None:
            self._server.stop()
            self._thread.join(5.0)
            if self._thread.is_alive():
                self._server.force_exit = True
                self._thread.join(5.0)
        self.sock.close()


def _server_class() -> Any:
    """uvicorn's Server, stopped at once: its own main loop looks whether to stop every 0.1 s, which would add
    that much to the end of every live run; this one is woken by :meth:`stop`."""
    import uvicorn

    class WokenServer(uvicorn.Server):
        _loop: asyncio.AbstractEventLoop | None = None
        _wake: asyncio.Event | None = None

        async def main_loop(self) -> None:
            self._loop, self._wake = asyncio.get_running_loop(), asyncio.Event()
            counter = 0
            while not await self.on_tick(counter):   # (on_tick: the date header, should_exit)
                counter = (counter + 1) % 864000
                try:
                    await asyncio.wait_for(self._wake.wait(), 0.1)
                except asyncio.TimeoutError:
                    pass

        async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
            """uvicorn's shutdown (stop accepting, ask each connection to close, wait for them and their
            tasks up to the graceful timeout, then cancel what is left) looking every 5 ms, not every 0.1 s."""
            for server in self.servers:
                server.close()
            for sock in sockets or []:
                sock.close()
            state = self.server_state
            for connection in list(state.connections):
                connection.shutdown()
            loop = asyncio.get_running_loop()
            deadline = loop.time() + float(self.config.timeout_graceful_shutdown or 2.0)
            while (state.connections or state.tasks) and not self.force_exit and loop.time() < deadline:
                await asyncio.sleep(0.005)
            for t in list(state.tasks):
                t.cancel()
            for server in self.servers:
                await server.wait_closed()
            if not self.force_exit:
                await self.lifespan.shutdown()

        def stop(self) -> None:
            """Stop serving (from another thread)."""
            self.should_exit = True
            loop, wake = self._loop, self._wake
            if loop is not None and wake is not None:
                try:
                    loop.call_soon_threadsafe(wake.set)
                except RuntimeError:   # the loop has closed
                    pass

    return WokenServer
