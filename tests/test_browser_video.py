"""The videos signlane writes play in a real browser: a short H.264 MP4 from VideoOut (the writer
of drive.mp4, `sim --video` and `infer` videos) opened by headless Chromium from the system
packages (Debian's `chromium`), driven by Playwright. Skipped where either is missing; .ci/run
installs both."""
import shutil

import numpy as np
import pytest

from signlane.video_out import VideoOut

pytestmark = pytest.mark.browser
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")

# resolves once the video has data, after 0.8 s of playing; or says why it could not play
PLAY = """() => new Promise(done => {
  const v = document.getElementById('v');
  const report = () => done({width: v.videoWidth, height: v.videoHeight, t: v.currentTime,
                             duration: v.duration, error: v.error && v.error.code});
  const go = () => v.play().then(() => setTimeout(report, 800), e => done({error: String(e)}));
  v.onerror = report;
  if (v.readyState >= 2) go(); else v.onloadeddata = go;
  setTimeout(report, 10000);
})"""


@pytest.mark.skipif(CHROMIUM is None, reason="no system Chromium (apt-get install chromium)")
def test_chromium_plays_the_videos_signlane_writes(tmp_path):
    with VideoOut(tmp_path / "drive.mp4", 30, (320, 240)) as video:
        for i in range(90):  # 3 s of a bar moving across
            frame = np.zeros((240, 320, 3), np.uint8)
            frame[:, (i * 3) % 300:(i * 3) % 300 + 20] = (0, 200, 255)
            video.write(frame)
    (tmp_path / "page.html").write_text('<video id="v" src="drive.mp4" muted playsinline></video>')
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            page = browser.new_page()
            page.goto((tmp_path / "page.html").as_uri())
            state = page.evaluate(PLAY)
        finally:
            browser.close()
    assert state["error"] is None, f"Chromium could not play drive.mp4: {state}"
    assert (state["width"], state["height"]) == (320, 240)
    assert state["duration"] == pytest.approx(3.0, abs=0.1)
    assert state["t"] > 0.2  # it played, not only loaded
