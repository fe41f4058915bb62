"""Schedulers and workers started as processes of their own by the tests of studies (not a test module)."""
from __future__ import annotations

import socket
import subprocess


def free_port() -> int:
    """A TCP port free on the loopback address now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop(procs: list[subprocess.Popen], timeout: float = 10) -> None:
    """End the processes, the last started first (workers before their scheduler); killed if they do not
    end within ``timeout`` [s]."""
    for pr in reversed(procs):
        pr.terminate()
    for pr in procs:
        try:
            pr.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pr.kill()
            pr.wait()
