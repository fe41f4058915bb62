"""The live view's page in a browser (docs/live.md): Playwright driving Debian's chromium headless through its
executable path.  The page of a live G1 run (cut short) loads, its plots receive points and are redrawn at
least 10 times a second, pause stops the time, a value set through the page's own control changes the
recorded signal from that time and appears in the event table, the XY path and the goal are drawn, and
``wmr-cosim view`` shows a finished run; the page loads nothing from another host.  Each test saves a
screenshot in its temporary folder (``LIVE_SCREENSHOTS=DIR`` also copies them there; docs/live.png is taken by
docs/live_screenshot.py)."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from wmr_cosim.cli import main

pytest.importorskip("starlette", reason="the live extra (starlette, uvicorn, websockets, tomli-w) is not installed")
pytest.importorskip("uvicorn")
pytest.importorskip("tomli_w")
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (the test extra) is not installed")

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    pytest.skip("Debian's package chromium is not installed (apt-get install chromium)", allow_module_level=True)

#: G1 with its requirements, cut short (the robot's scenarios name [live] xy = plant.x_A, plant.y_A).
SCENARIO = f'base = "{(ROOT / "scenarios" / "g1_requirements.toml").as_posix()}"\n[experiment]\nstop = 6.0\n'
STEP = 0.002


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """Chromium headless, its temporary files in a folder of the test's (removed with it)."""
    tmp = tmp_path_factory.mktemp("browser-tmp")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TMPDIR", str(tmp))
        mp.setattr(tempfile, "tempdir", str(tmp))
        with sync_api.sync_playwright() as pw:
            b = pw.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu"],
                                   env={**os.environ, "TMPDIR": str(tmp)})
            try:
                yield b
            finally:
                b.close()
    shutil.rmtree(tmp, ignore_errors=True)


@pytest.fixture
def work(tmp_path):
    (tmp_path / "tmp").mkdir()
    (tmp_path / "g1.toml").write_text(SCENARIO)
    yield tmp_path
    assert not list((tmp_path / "tmp").iterdir())


def _env(work: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(work / "tmp")}


def _serve(work: Path, *argv: str) -> tuple[subprocess.Popen, str]:
    """``wmr-cosim ARGV`` in a child process, and the address it printed."""
    p = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", *argv], cwd=work, env=_env(work),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert p.stderr is not None
    line = p.stderr.readline()
    if not line.startswith("live view: "):
        p.kill()
        pytest.fail(f"no address: {line}{p.communicate()[1]}")
    return p, line.split(": ", 1)[1].strip()


def _finish(p: subprocess.Popen, timeout: float = 120) -> tuple[int, str]:
    """The exit code and stderr of ``p`` once it has ended (killed if it has not within ``timeout``)."""
    try:
        _, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    return p.returncode, err


def _kill(p: subprocess.Popen) -> None:
    """A child a failed test left running, ended."""
    if p.poll() is None:
        p.kill()
        p.communicate()


def _wait(what: Callable[[], Any], timeout: float = 30.0, why: str = "") -> Any:
    """Poll ``what()`` until it is true (the page's CSP forbids the string evaluation wait_for_function uses)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        value = what()
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(f"timed out waiting for {why or what}")


class Page:
    """A page of the browser at ``url``, with the errors it raised and every address it asked for."""

    def __init__(self, browser: Any, url: str) -> None:
        self.page = browser.new_page(viewport={"width": 1400, "height": 1000})
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.goto(url)

    def stats(self) -> dict[str, Any]:
        return self.page.evaluate("({...window.liveStats})")

    def time(self) -> float:
        return float(self.page.text_content("#time") or "nan")

    def status(self) -> str:
        return self.page.text_content("#status") or ""

    def shot(self, path: Path) -> None:
        self.page.screenshot(path=str(path), full_page=True)
        if os.environ.get("LIVE_SCREENSHOTS"):
            shutil.copy(path, Path(os.environ["LIVE_SCREENSHOTS"]) / path.name)

    def colour_pixels(self, canvas: str, rgb: tuple[int, int, int]) -> int:
        """How many pixels of the canvas are about this colour (what was drawn in it)."""
        return self.page.evaluate("""([id, rgb]) => {
            const c = document.getElementById(id), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0;
            for (let i = 0; i < d.length; i += 4)
              if (Math.abs(d[i] - rgb[0]) < 40 && Math.abs(d[i + 1] - rgb[1]) < 40 && Math.abs(d[i + 2] - rgb[2]) < 40 && d[i + 3] > 200) n++;
            return n; }""", [canvas, list(rgb)])


def _origin(url: str) -> str:
    return url.split("/")[2]


def test_the_page_of_a_live_run_plots_pauses_and_draws_the_path(browser, work):
    p, url = _serve(work, "run", "g1.toml", "--out", "out", "--quiet", "--live", "--paused")
    try:
        pg = Page(browser, url)
        _wait(lambda: pg.stats()["rows"] >= 1 and pg.stats()["charts"] >= 1, why="the first row and a plot")
        # the variables grouped by unit, the XY path's two shown; the requirements listed; the settable ones
        units = pg.page.eval_on_selector_all("#vars h3", "hs => hs.map(h => h.textContent)")
        assert "[m]" in units and "[N.m]" in units and "[rad]" in units
        shown = pg.page.eval_on_selector_all("#vars input:checked", "bs => bs.map(b => b.dataset.column)")
        assert shown[:2] == ["plant.x_A", "plant.y_A"]
        axes = pg.page.eval_on_selector_all("#charts .chart", "cs => cs.map(c => c.dataset.unit)")
        assert "m" in axes and len(axes) == len(set(axes))   # one plot per unit
        reqs = pg.page.eval_on_selector_all("#requirements tbody tr td:first-child", "ts => ts.map(t => t.textContent)")
        assert reqs == ["torque", "goal", "tracking"]
        # paced at 1x through the page's own control, resumed: rows arrive and the plots are redrawn >= 10 / s
        pg.page.select_option("#rate", "1")
        _wait(lambda: "pace: 1x" in pg.status(), why="the pace 1x")
        pg.page.click("#resume")
        _wait(lambda: (pg.stats()["lastTime"] or 0) > 0.5, why="half a second of the run")
        s0, t0 = pg.stats(), time.monotonic()
        time.sleep(1.0)
        s1, dt = pg.stats(), time.monotonic() - t0
        assert (s1["rows"] - s0["rows"]) / dt >= 10 and (s1["draws"] - s0["draws"]) / dt >= 10, (s0, s1, dt)
        assert "real-time factor" in pg.status()
        # pause stops the time
        pg.page.click("#pause")
        _wait(lambda: "paused" in pg.status(), why="paused")
        t_paused = pg.time()
        time.sleep(0.6)
        assert pg.time() == t_paused and 0.5 < t_paused < 6.0
        rows = pg.stats()["rows"]
        time.sleep(0.3)
        assert pg.stats()["rows"] == rows
        # the XY path and the goal (2, 5) drawn
        assert pg.stats()["xyPoints"] >= 10                       # the path's points (the robot has hardly left (0, 0))
        assert pg.colour_pixels("xy", (0xd6, 0x27, 0x28)) > 20   # where it is now
        assert pg.colour_pixels("xy", (0x2c, 0xa0, 0x2c)) > 20   # the goal's ring and cross
        assert "goal" in (pg.page.text_content("#xytitle") or "")
        pg.shot(work / "live.png")
        # nothing from another host: every request the page made went to the run's own server
        assert pg.requests and {_origin(u) for u in pg.requests if not u.startswith("data:")} == {_origin(url)}
        html = pg.page.content()
        assert "http://" not in html and "https://" not in html
        assert not pg.errors, pg.errors
        pg.page.click("#stop")
        code, err = _finish(p)
        assert code == 0, err
    finally:
        _kill(p)
    assert json.loads((work / "out" / "summary.json").read_text())["status"] == "stopped"


def test_a_value_set_through_the_page_acts_from_that_time_and_is_in_the_event_table(browser, work):
    p, url = _serve(work, "run", "g1.toml", "--out", "out", "--quiet", "--live", "--paused")
    try:
        pg = Page(browser, url)
        _wait(lambda: pg.stats()["rows"] >= 1, why="the first row")
        pg.page.fill("#steps", "500")
        pg.page.click("#step")
        _wait(lambda: pg.time() == 1.0, why="500 steps")
        pg.page.select_option("#setvar", "controller.goal_x")
        assert (pg.page.text_content("#setunit") or "").strip() == "m"   # its unit, min and max shown
        assert "min" in (pg.page.text_content("#setinfo") or "") and "max" in (pg.page.text_content("#setinfo") or "")
        pg.page.fill("#setval", "3")
        pg.page.click("#set")
        time.sleep(0.3)
        assert (pg.page.text_content("#error") or "") == ""
        pg.page.fill("#steps", "10")
        pg.page.click("#step")
        _wait(lambda: pg.time() == 1.02, why="10 steps more")
        with urllib.request.urlopen(url.rstrip("/") + "/api/state", timeout=30) as r:
            assert json.loads(r.read())["xy"]["goals"] == [[3.0, 5.0]]   # the goal moved with the value set
        pg.page.select_option("#rate", "0")
        pg.page.click("#resume")
        _wait(lambda: " ok" in pg.status(), why="the end of the run")
        rows = pg.page.eval_on_selector_all("#events tbody tr", "rs => rs.map(r => [...r.cells].map(c => c.textContent))")
        assert ["1.0000", "controller.goal_x", "set", "3", "live"] in rows, rows
        assert pg.page.evaluate("document.querySelector('#xytitle').textContent").endswith("goal marked")
        pg.shot(work / "set.png")
        assert not pg.errors, pg.errors
        code, err = _finish(p)
        assert code == 0, err
    finally:
        _kill(p)
    events = json.loads((work / "out" / "summary.json").read_text())["events"]
    assert [(e["time"], e["variable"], e["value"], e["source"]) for e in events] == [(1.0, "controller.goal_x", 3.0, "live")]
    assert main(["run", str(work / "g1.toml"), "--out", str(work / "plain"), "--quiet"]) == 0
    live, plain = np.load(work / "out" / "signals.npy"), np.load(work / "plain" / "signals.npy")
    before = live["time"] <= 1.0
    assert live[before].tobytes() == plain[before].tobytes()            # the same up to the time it was set
    assert not np.array_equal(live["controller.u1"][~before], plain["controller.u1"][~before])   # ... not after
    assert main(["run", str(work / "out" / "replay.toml"), "--out", str(work / "replay"), "--quiet"]) == 0
    assert (work / "replay" / "signals.npy").read_bytes() == (work / "out" / "signals.npy").read_bytes()


def test_view_shows_a_finished_run(browser, work):
    assert main(["run", str(work / "g1.toml"), "--out", str(work / "done"), "--quiet"]) == 0
    p, url = _serve(work, "view", "done")
    try:
        pg = Page(browser, url)
        n = len(np.load(work / "done" / "signals.npy"))
        _wait(lambda: pg.stats()["rows"] == n, why=f"the {n} rows")
        assert pg.stats()["charts"] >= 1 and pg.stats()["xyPoints"] == n
        assert "view: done" in (pg.page.text_content("#title") or "") and " ok" in pg.status()
        assert pg.time() == 6.0
        assert not pg.page.is_visible("#controls")   # nothing to steer
        verdicts = pg.page.eval_on_selector_all("#requirements tbody tr", "rs => rs.map(r => r.cells[1].textContent)")
        assert verdicts == ["holds", "undecided", "undecided"]
        assert pg.colour_pixels("xy", (0x2c, 0xa0, 0x2c)) > 20
        pg.shot(work / "view.png")
        assert not pg.errors, pg.errors
    finally:
        p.send_signal(signal.SIGINT)
        code, err = _finish(p, 30)
    assert code == 0, err


def test_view_of_a_folder_that_is_not_a_results_folder_is_one_line_and_exit_2(work):
    (work / "empty").mkdir()
    for folder in ("empty", "nothing-here", "g1.toml"):
        p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "view", folder], cwd=work, env=_env(work),
                           capture_output=True, text=True, timeout=60)
        lines = p.stderr.strip().splitlines()
        assert p.returncode == 2 and len(lines) == 1 and folder in lines[0], (folder, p.stderr)
