"""``wmr-cosim view RESULTS``: a finished run's folder served in the live view's page (its signals, event
table and requirements' verdicts) until interrupted (Ctrl-C)."""
from __future__ import annotations

import threading
from pathlib import Path
from typing import Callable

from .run import LiveError, LiveOptions, announce_url, bind_server, missing_libraries


def serve_results(folder: str | Path, options: LiveOptions, announce: Callable[[str], None] | None = None,
                  until: threading.Event | None = None) -> None:
    """Serve the results folder ``folder`` on ``options``' host and port until Ctrl-C (or ``until`` is
    set); ``announce(url)`` is told the page's address once the server listens (default: the line
    ``live view: URL`` on stderr).  LiveError (one line, nothing served) for a folder that is not a results
    folder, a port that cannot be bound or the live extra missing."""
    missing = missing_libraries()
    if missing:
        raise LiveError(f"view needs {', '.join(missing)} (the live extra): pip install 'wmr-cosim[live]'")
    from .finished import FinishedRun, NotResults

    try:
        source = FinishedRun(folder)
    except NotResults as exc:
        raise LiveError(str(exc)) from None
    server = bind_server(options)
    done = until or threading.Event()
    try:
        server.start(source)
        (announce or announce_url)(server.url)
        while not done.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
