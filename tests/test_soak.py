"""The drive-server soak (benchmarks/soak.py): 60 frames/s for 3 minutes, every frame answered,
the server's memory flat within 20 MB. Slow: run with `pytest -m slow tests/test_soak.py`
(SIGNLANE_SOAK_SECONDS shortens it)."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_soak_every_frame_answered_and_memory_flat():
    seconds = os.environ.get("SIGNLANE_SOAK_SECONDS", "180")
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "soak.py"), "--seconds", seconds, "--fps", "60",
                          "--check", "--max-growth-mb", "20"], capture_output=True, text=True, cwd=ROOT,
                         timeout=float(seconds) + 300)
    rows = dict(line.split(None, 1) for line in run.stdout.splitlines() if len(line.split(None, 1)) == 2)
    assert run.returncode == 0, run.stdout + run.stderr
    assert int(rows["sent"]) >= 55 * float(seconds) and rows["answered"] == rows["sent"]
    assert float(rows["growth_mb"]) <= 20.0
