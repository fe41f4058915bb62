"""``run --live`` and ``Simulation.run(live=True)`` driven through their HTTP and WebSocket API
(docs/live.md): a run started paused, stepped, given values, paced, resumed to its end; the values set
replay byte for byte from replay.toml; pauses, steps and pacing change nothing; the token on another
interface; a port in use; the server gone with the run."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from reference_fmus import REF
from wmr_cosim.cli import main

pytest.importorskip("starlette", reason="the live extra (starlette, uvicorn, websockets, tomli-w) is not installed")
pytest.importorskip("uvicorn")
pytest.importorskip("tomli_w")
ws_client = pytest.importorskip("websockets.sync.client")

ROOT = Path(__file__).resolve().parents[1]
STEP = 0.01

#: A bouncing ball (its coefficient of restitution e: tunable, 0.5 to 1) feeding a Feedthrough: 300 steps.
SCENARIO = f"""[experiment]
stop = 3.0
step = {STEP!r}
[instances.bb]
fmu = "{REF / 'fmi2' / 'BouncingBall.fmu'}"
[instances.f]
fmu = "{REF / 'fmi2' / 'Feedthrough.fmu'}"
[[connections]]
from = "bb.h"
to = "f.Float64_continuous_input"
[record]
variables = ["bb.h", "bb.v", "f.Float64_continuous_output", "f.Float64_discrete_output", "f.Int32_output"]
"""


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A working folder with the scenario, and a temporary folder of its own that must be empty at the end."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setenv("TMPDIR", str(tmp))
    (tmp_path / "s.toml").write_text(SCENARIO)
    yield tmp_path
    assert not list(tmp.iterdir()), f"left in the temporary folder: {list(tmp.iterdir())}"


class Client:
    """HTTP requests to a live run at ``url`` (its page's address, with the token where it has one)."""

    def __init__(self, url: str) -> None:
        base, _, query = url.partition("?")
        self.base, self.query = base.rstrip("/"), (f"?{query}" if query else "")

    def __call__(self, path: str, body: dict | None = None, post: bool | None = None, query: str | None = None,
                 headers: dict | None = None) -> tuple[int, dict]:
        q = self.query if query is None else query
        data = json.dumps(body).encode() if body is not None else (b"" if post else None)
        req = urllib.request.Request(f"{self.base}{path}{q}", data=data, method="POST" if data is not None else "GET",
                                     headers=headers or {})
        try:
            with urllib.request.urlopen(req, timeout=30) as r:
                return r.status, json.loads(r.read())
        except urllib.error.HTTPError as exc:
            return exc.code, json.loads(exc.read())

    def ws(self, query: str | None = None):
        return ws_client.connect(f"{self.base.replace('http://', 'ws://')}/api/stream"
                                 f"{self.query if query is None else query}", open_timeout=30)


def _start(work: Path, *options: str) -> tuple[subprocess.Popen, str]:
    """``wmr-cosim run s.toml --out out --live OPTIONS`` in a child process, and the address it printed."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(work / "tmp")}
    p = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", "run", "s.toml", "--out", "out", "--quiet", "--live",
                          *options], cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert p.stderr is not None
    line = p.stderr.readline()
    if not line.startswith("live view: "):
        p.kill()
        pytest.fail(f"no address: {line}{p.communicate()[1]}")
    return p, line.split(": ", 1)[1].strip()


def _finish(p: subprocess.Popen) -> tuple[int, str, str]:
    try:
        out, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    return p.returncode, out, err


def test_a_live_run_paused_stepped_set_and_resumed_replays_byte_for_byte(work):
    p, url = _start(work, "--paused")
    assert url.startswith("http://127.0.0.1:") and "token" not in url
    try:
        api = Client(url)
        code, st = api("/api/state")
        assert code == 200 and st["paused"] and st["steps"] == 0 and st["time"] == 0.0 and st["stop_time"] == 3.0
        assert {"name": "bb.h", "unit": "m"} in st["variables"]
        e = next(v for v in st["settable"] if v["name"] == "bb.e")
        assert (e["min"], e["max"], e["causality"]) == (0.5, 1.0, "parameter")
        time.sleep(0.3)
        assert api("/api/state")[1]["steps"] == 0   # paused: no step taken
        code, st = api("/api/step", {"steps": 10})
        assert code == 200 and st["steps"] == 10 and st["time"] == 0.0 + 10 * STEP and st["paused"]
        # refused, one line each: out of the declared range, an output, a fixed parameter, no such variable
        for body, words in (({"variable": "bb.e", "value": 0.3}, ["bb.e", "minimum 0.5"]),
                            ({"variable": "bb.h", "value": 1.0}, ["bb.h", "output", "tunable parameters and inputs"]),
                            ({"variable": "bb.g", "value": 1.0}, ["bb.g", "fixed parameter"]),
                            ({"variable": "bb.nope", "value": 1.0}, ["nope"]),
                            ({"variable": "bb.e", "value": "x"}, ["bb.e", "type mismatch"]),
                            ({"variable": "bb.e"}, ["bb.e", "value"])):
            code, err = api("/api/set", body)
            assert code == 400 and "\n" not in err["error"] and all(w in err["error"] for w in words), (body, err)
        assert api("/api/step", {"steps": 0})[0] == 400
        assert api("/api/rate", {"factor": -1})[0] == 400
        assert api("/api/set", {"variable": "bb.e", "value": 0.6})[0] == 200                     # a tunable parameter
        assert api("/api/set", {"variable": "f.Float64_continuous_input", "value": 5})[0] == 200  # a connected input
        assert api("/api/set", {"variable": "f.Int32_input", "value": 7})[0] == 200               # an input alone
        assert api("/api/set", {"variable": "f.Float64_discrete_input", "value": 2.5})[0] == 200  # a Real one alone
        with api.ws() as ws:
            head = json.loads(ws.recv())
            assert head["type"] == "columns" and head["columns"][:2] == ["time", "bb.h"]
            assert head["units"][:3] == ["s", "m", "m/s"]
            assert api("/api/rate", {"factor": 0})[0] == 200
            code, st = api("/api/resume", post=True)
            assert code == 200 and not st["paused"]
            rows = []
            while (msg := json.loads(ws.recv()))["type"] == "row":
                rows.append(msg["row"])
            assert msg["type"] == "end" and msg["state"]["status"] == "ok" and msg["state"]["time"] == 3.0
        times = [r[0] for r in rows]
        assert rows and times == sorted(times) and times[-1] == 3.0
        code, out, err = _finish(p)
        assert code == 0, err
    finally:
        _finish(p)
    out = work / "out"
    events = json.loads((out / "summary.json").read_text())["events"]
    assert [(e["source"], e["time"], e["variable"], e["value"]) for e in events] == [
        ("live", 0.1, "bb.e", 0.6), ("live", 0.1, "f.Float64_continuous_input", 5.0), ("live", 0.1, "f.Int32_input", 7),
        ("live", 0.1, "f.Float64_discrete_input", 2.5)]
    assert main(["run", str(out / "replay.toml"), "--out", str(work / "replay"), "--quiet"]) == 0
    live = (out / "signals.npy").read_bytes()
    assert (work / "replay" / "signals.npy").read_bytes() == live
    assert main(["run", str(work / "s.toml"), "--out", str(work / "plain"), "--quiet"]) == 0
    assert (work / "plain" / "signals.npy").read_bytes() != live   # (the values set changed the run)


def test_pauses_steps_and_pacing_change_nothing_and_the_server_ends_with_the_run(work):
    """Through the Python API: a run paused, stepped, paced at 5x and resumed gives the plain run's signals."""
    from wmr_cosim import Simulation

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    sim = Simulation.load(work / "s.toml")
    done: dict = {}
    runner = threading.Thread(target=lambda: done.update(r=sim.run(work / "live", live=True, port=port, paused=True)))
    runner.start()
    try:
        api = Client(f"http://127.0.0.1:{port}/")
        for _ in range(300):
            try:
                code, st = api("/api/state")
                break
            except urllib.error.URLError:
                time.sleep(0.1)
        assert code == 200 and st["paused"]
        assert api("/api/step", {"steps": 7})[1]["steps"] == 7
        assert api("/api/step", post=True)[1]["steps"] == 8
        assert api("/api/rate", {"factor": 5})[1]["rate"] == 5.0
        assert api("/api/resume", post=True)[0] == 200
        time.sleep(0.3)
        code, st = api("/api/pause", post=True)
        assert code == 200 and st["paused"] and 8 < st["steps"] < 300
        assert st["real_time_factor"] is None or 2.5 < st["real_time_factor"] < 6   # (measured since the resume)
        k = st["steps"]
        time.sleep(0.2)
        assert api("/api/state")[1]["steps"] == k
        assert api("/api/rate", {"factor": 0})[0] == 200
        assert api("/api/resume", post=True)[0] == 200
    finally:
        runner.join(60)
    assert not runner.is_alive()
    result = done["r"]
    assert result.status == "ok" and result.steps == 300 and result.summary["real_time"]["factor"] == 5.0
    assert [t.name for t in threading.enumerate() if "live" in t.name] == []
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()   # nothing listens any more
    assert main(["run", str(work / "s.toml"), "--out", str(work / "plain"), "--quiet"]) == 0
    assert (work / "plain" / "signals.npy").read_bytes() == (work / "live" / "signals.npy").read_bytes()
    assert (work / "live" / "replay.toml").is_file()


def test_another_interface_requires_the_token_on_every_request(work):
    p, url = _start(work, "--paused", "--host", "0.0.0.0")
    try:
        assert "?token=" in url
        token = url.split("?token=", 1)[1]
        api = Client(url.replace("0.0.0.0", "127.0.0.1"))
        assert api("/api/state")[0] == 200
        assert api("/api/state", headers={"Authorization": f"Bearer {token}"}, query="")[0] == 200
        for query in ("", "?token=", f"?token={token[:-1]}", f"?token={token}x"):
            assert api("/api/state", query=query)[0] == 403
            assert api("/api/pause", post=True, query=query)[0] == 403
            assert api("/", query=query)[0] == 403
            with pytest.raises(Exception, match="403"):
                api.ws(query=query).close()
        # no cross-origin access, even with the token
        assert api("/api/state", headers={"Origin": "http://example.com"})[0] == 403
        assert api("/api/state")[1]["steps"] == 0
        code, st = api("/api/stop", post=True)
        assert code == 200 and st["status"] == "stopped"
        assert _finish(p)[0] == 0
    finally:
        _finish(p)


def test_loopback_answers_only_its_own_host_name(work):
    """A page of another site whose name resolves to 127.0.0.1 (DNS rebinding) is refused."""
    p, url = _start(work, "--paused")
    try:
        api = Client(url)
        assert api("/api/state", headers={"Host": "evil.example:80"})[0] == 403
        assert api("/api/state", headers={"Origin": "http://evil.example"})[0] == 403
        page = urllib.request.urlopen(url, timeout=30).read().decode()
        assert "http://" not in page.replace(url, "") and "https://" not in page   # nothing from another host
        assert api("/api/stop", post=True)[0] == 200
        assert _finish(p)[0] == 0
    finally:
        _finish(p)


def test_a_port_in_use_is_one_line_and_exit_2(work, capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        code = main(["run", str(work / "s.toml"), "--out", str(work / "out"), "--quiet", "--live", "--port", str(port)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"--port {port}" in err[0] and "in use" in err[0], err
    assert not (work / "out").exists()


@pytest.mark.parametrize("xy, words", [
    ('["bb.h"]', ["live.xy", "two names"]),
    ('["bb.h", "bb.h"]', ["live.xy", "two different names"]),
    ('"bb.h"', ["live.xy", "two names"]),
    ('["bb.h", "nope.v"]', ["live.xy[1]", "unknown instance 'nope'"]),
    ('["bb.h", "bb.nope"]', ["live.xy[1]", "no variable 'nope'"]),
])
def test_live_xy_names_two_recorded_variables_else_check_says_so_in_one_line(work, capsys, xy, words):
    (work / "s.toml").write_text(SCENARIO + f"[live]\nxy = {xy}\n")
    code = main(["check", str(work / "s.toml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and all(w in err[0] for w in words), err


def test_live_xy_not_recorded_is_a_note_and_no_path(work, capsys):
    """A base's [live] must not refuse a file that records less: the path is not drawn, check says why."""
    from wmr_cosim import Simulation

    (work / "s.toml").write_text(SCENARIO + '[live]\nxy = ["bb.h", "f.Float64_continuous_input"]\n')
    assert main(["check", str(work / "s.toml")]) == 0
    out = capsys.readouterr().out
    assert "[live] xy: f.Float64_continuous_input is not recorded: the live view draws no path" in out, out
    plan = Simulation.load(work / "s.toml").check()
    assert plan.scenario.xy == []


def test_live_xy_is_in_the_state_and_the_robots_scenarios_name_it(work):
    from wmr_cosim.cosim import read_document

    (work / "s.toml").write_text(SCENARIO + '[live]\nxy = ["bb.h", "bb.v"]\n')
    assert main(["check", str(work / "s.toml")]) == 0
    p, url = _start(work, "--paused")
    try:
        code, st = Client(url)("/api/state")
        assert code == 200 and st["xy"] == {"x": "bb.h", "y": "bb.v", "units": ["m", "m/s"], "goals": []}
        assert st["requirements"] == [] and st["mode"] == "live"
        assert Client(url)("/api/stop", post=True)[0] == 200
        assert _finish(p)[0] == 0
    finally:
        _finish(p)
    for name in ("g1_learn.toml", "g1_requirements.toml", "example.toml", "paper/g1.toml", "paper/line.toml"):
        assert read_document(ROOT / "scenarios" / name)["live"] == {"xy": ["plant.x_A", "plant.y_A"]}, name


@pytest.mark.parametrize("browser", [True, False])
def test_open_gives_the_page_to_the_browser_or_says_it_cannot(work, capsys, monkeypatch, browser):
    """--open hands the page's address (the one printed) to the default browser once the server listens;
    where no browser can be started, one note says so and the run goes on."""
    import webbrowser

    opened: list[str] = []
    monkeypatch.setattr(webbrowser, "open", lambda url, *a, **k: opened.append(url) or browser)
    assert main(["run", str(work / "s.toml"), "--out", str(work / "out"), "--quiet", "--live", "--open"]) == 0
    err = capsys.readouterr().err
    address = next(ln for ln in err.splitlines() if ln.startswith("live view: http"))
    assert opened == [address.split(": ", 1)[1]]
    assert ("no web browser could be opened" in err) is (not browser)
