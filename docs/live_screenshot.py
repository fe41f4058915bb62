"""docs/live.png: the live view's page on G1 on foam (scenarios/g1_requirements.toml), stepped to 28 s through
the page's own controls with a torque disturbance set from 12 s to 16 s, in Debian's chromium headless
(Playwright, the test extra).  ``python docs/live_screenshot.py`` from the checkout."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from PIL import Image
from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        p = subprocess.Popen([sys.executable, "-m", "wmr_cosim.cli", "run", str(ROOT / "scenarios" / "g1_requirements.toml"),
                              "--out", str(Path(tmp) / "run"), "--quiet", "--live", "--paused"],
                             env=env, stderr=subprocess.PIPE, text=True)
        assert p.stderr is not None
        url = p.stderr.readline().split(": ", 1)[1].strip()
        with sync_playwright() as pw:
            b = pw.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
            page = b.new_page(viewport={"width": 1280, "height": 1000})
            page.goto(url)
            time.sleep(1)

            def step(n: int) -> None:
                page.fill("#steps", str(n))
                page.click("#step")
                time.sleep(2)

            def give(variable: str, value: str) -> None:
                page.select_option("#setvar", variable)
                page.fill("#setval", value)
                page.click("#set")
                time.sleep(0.3)
            step(6000)
            give("plant.tau_d1", "0.3")
            step(2000)
            give("plant.tau_d1", "0")
            step(6000)
            for column in ("controller.u1", "controller.u2", "plant.alpha1", "plant.alpha2", "controller.e1",
                           "controller.e2"):
                page.click(f"input[data-column='{column}']")
            page.select_option("#setvar", "controller.goal_x")
            time.sleep(1)
            shot = Path(tmp) / "shot.png"
            page.screenshot(path=str(shot), full_page=True)
            page.click("#stop")
            b.close()
        p.wait(60)
        im = Image.open(shot).convert("RGB")
        im = im.resize((im.width * 3 // 4, im.height * 3 // 4), Image.LANCZOS)
        im.quantize(128, method=Image.Quantize.FASTOCTREE).save(ROOT / "docs" / "live.png", optimize=True)


if __name__ == "__main__":
    main()
