"""The live monitor in a real browser: headless Chromium (Debian's, driven by Playwright) opens
the page of a lockstep `signlane sim --with-driver` run, sees the camera image update, switches
topics and reads the live steering value, which must be the command the driver sent for the
frame on screen. Skipped where Chromium or Playwright is missing; .ci/run installs both."""
import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request

import pytest

pytestmark = pytest.mark.browser
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")

CANVAS_HASH = """() => { const c = document.getElementById('view');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let h = 0; for (let i = 0; i < d.length; i += 97) h = (h * 31 + d[i]) >>> 0; return h; }"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def api_state(port: int) -> dict:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state", timeout=5) as r:
        return json.loads(r.read())


@pytest.fixture()
def sim_run():
    """A lockstep simulator run with its drive server (and monitor) on a known port."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "signlane.cli", "sim", "--with-driver", "--lockstep",
                             "--port", str(port), "--max-seconds", "120"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 90
        while True:
            assert proc.poll() is None, f"sim exited: {proc.stderr.read()[-2000:]}"
            try:
                if api_state(port)["seq"] > 0:
                    break
            except OSError:
                pass
            assert time.monotonic() < deadline, "the monitor never showed a driven frame"
            time.sleep(0.2)
        yield port
    finally:
        proc.terminate()
        proc.wait(30)


@pytest.mark.skipif(CHROMIUM is None, reason="no system Chromium (apt-get install chromium)")
def test_monitor_page_shows_the_live_drive(sim_run, tmp_path):
    port = sim_run
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(f"http://127.0.0.1:{port}/")
            page.wait_for_function("() => window.monitor && window.monitor.frames() >= 3", timeout=30000)
            first = page.evaluate(CANVAS_HASH)
            n = page.evaluate("() => window.monitor.frames()")
            page.wait_for_function(f"() => window.monitor.frames() >= {n + 5}", timeout=30000)
            assert page.evaluate(CANVAS_HASH) != first  # the image updates as the car drives
            # the live steering value is the command the driver sent for the frame on screen
            page.wait_for_function("() => /^#\\d+ /.test(document.getElementById('frame').textContent)")
            text = page.evaluate("() => [document.getElementById('steering').textContent,"
                                 " document.getElementById('frame').textContent]")
            steering, seq = float(text[0]), int(text[1].split()[0][1:])
            sent = {s[0]: s[2] for s in api_state(port)["samples"]}
            assert seq in sent and abs(steering - sent[seq]) <= 0.0006 and -1 <= steering <= 1
            page.screenshot(path=str(tmp_path / "monitor.png"), full_page=True)
            page.click("#topics button[data-topic=birdseye]")
            page.wait_for_function("() => document.getElementById('frame').textContent.includes('(birdseye)')",
                                   timeout=30000)
            bev = page.evaluate(CANVAS_HASH)
            n = page.evaluate("() => window.monitor.frames()")
            page.wait_for_function(f"() => window.monitor.frames() >= {n + 2}", timeout=30000)
            assert page.evaluate("() => window.monitor.topic()") == "birdseye"
            assert page.evaluate(CANVAS_HASH) != bev
            assert api_state(port)["viewers"] == 1
        finally:
            browser.close()
    if os.environ.get("SIGNLANE_MONITOR_SCREENSHOT"):  # to look at it: SIGNLANE_MONITOR_SCREENSHOT=/tmp/monitor.png
        shutil.copy(tmp_path / "monitor.png", os.environ["SIGNLANE_MONITOR_SCREENSHOT"])
