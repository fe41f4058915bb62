"""A live run: the server bound, the run initialised and stepped by a :class:`.session.LiveSession` in the
calling thread while the server runs in its own, then ``replay.toml`` written into the results folder."""
from __future__ import annotations

import copy
import importlib.util
import secrets
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..cosim import CosimError, Execution, Plan, RunResult

#: The libraries of the ``live`` extra (import names).
LIBRARIES = ("starlette", "uvicorn", "websockets", "tomli_w")

REPLAY_FILE = "replay.toml"


class LiveError(CosimError):
    """A live run that cannot start (its port in use, its libraries missing): bad input, one line."""


@dataclass(frozen=True)
class LiveOptions:
    """How a run is served: ``host`` (an address; 127.0.0.1 by default, another interface requires a
    token), ``port`` (0: a free one), ``paused`` (the run starts paused), ``open`` (the page opened in the
    default web browser once the server listens)."""

    host: str = "127.0.0.1"
    port: int = 0
    paused: bool = False
    open: bool = False


def missing_libraries() -> list[str]:
    """The libraries of the ``live`` extra that are not installed."""
    return [m for m in LIBRARIES if importlib.util.find_spec(m) is None]


def replay_document(plan: Plan, given: list[dict[str, Any]]) -> dict[str, Any]:
    """The scenario of a live run (its document as merged and overridden) with the values set during it
    appended to its ``[[events]]`` as timed events (time, variable, action, value)."""
    doc = copy.deepcopy(plan.scenario.data)
    if given:
        doc["events"] = list(doc.get("events") or []) + [dict(e) for e in given]
    return _plain(doc)


def _plain(obj: Any) -> Any:
    """A document TOML can hold (paths as strings)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_replay(folder: Path, plan: Plan, given: list[dict[str, Any]]) -> Path:
    """``replay.toml`` in the results folder (see :func:`replay_document`)."""
    import tomli_w

    text = ("# The scenario of a live run, with the values set during it as timed [[events]] (source \"live\" in\n"
            "# summary.json's events): `wmr-cosim run replay.toml` gives the same signals.npy, byte for byte.\n"
            + tomli_w.dumps(replay_document(plan, given)))
    path = folder / REPLAY_FILE
    path.write_text(text, encoding="utf-8")
    return path


def run_live(plan: Plan, out: str | Path | None, options: LiveOptions, real_time: float | None = None,
             keep_signals: bool = False, announce: Callable[[str], None] | None = None) -> RunResult:
    """Run ``plan`` into the results folder ``out`` served live (``options``); ``real_time``: the pace it
    starts at; ``announce(url)`` is told the page's address once the server listens (default: the line
    ``live view: URL`` on stderr).  The server ends with the run, leaving no thread.  LiveError (before
    anything is written) where the port cannot be bound or the libraries are missing."""
    missing = missing_libraries()
    if missing:
        raise LiveError(f"--live needs {', '.join(missing)} (the live extra): pip install 'wmr-cosim[live]'")
    from .session import LiveSession

    server = bind_server(options)
    try:
        ex = Execution(plan, out, progress=False, keep_signals=keep_signals)
        try:
            ex.initialize()
        except (CosimError, KeyboardInterrupt):
            return ex.close()   # the run has ended: its status and message say how
        session = LiveSession(ex, paused=options.paused, factor=real_time)
        server.start(session)
        (announce or announce_url)(server.url)
        if options.open:
            open_page(server.url)
        try:
            session.drive()
        finally:
            server.close()
    finally:
        server.sock.close()
    result = ex.close()
    if result.out_dir is not None:
        write_replay(Path(result.out_dir), plan, session.given)
    return result


def bind_server(options: LiveOptions) -> Any:
    """A :class:`.server.LiveServer` bound to ``options``' address and port, with a random token where the
    address is not loopback; LiveError (one line) where the port cannot be bound."""
    from .server import LiveServer, is_loopback

    token = None if is_loopback(options.host) else secrets.token_urlsafe(24)
    try:
        return LiveServer(options.host, options.port, token)
    except OSError as exc:
        raise LiveError(f"--port {options.port}: cannot serve on {options.host}:{options.port} "
                        f"({exc.strerror or exc})") from None


def open_page(url: str) -> None:
    """The page at ``url`` in the default web browser (Python's webbrowser); where none can be started, a
    note on stderr (the address is printed already)."""
    import webbrowser

    try:
        opened = webbrowser.open(url)
    except webbrowser.Error:
        opened = False
    if not opened:
        print("live view: note: no web browser could be opened here; open the address above", file=sys.stderr,
              flush=True)


def announce_url(url: str) -> None:
    print(f"live view: {url}", file=sys.stderr, flush=True)
