"""Every command block of the README runs as written, in the order shown, in a fresh working
folder (part of `make test`: 2-4 minutes on 2 cores).

Sizes are shrunk so the whole README runs in minutes (`--n` at most 40, one epoch, 4 simulated
seconds a drive, one seed); what each command is and the order they come in are the README's.
Where a command would change the installation or run without end, it is adapted and said so:
`ship` copies into a scratch models folder (`--into`), a `drive` server is stopped once it
listens. Not run: `make test` (this suite), the `pip install` lines (the environment this test
runs in) and the closed-loop benchmark (minutes a track; its numbers in the README come from it).
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOT_RUN = ("make test", "pip install", "benchmarks/closed_loop.py")


def readme_commands() -> list[str]:
    """The lines of the README's ```bash blocks, in order."""
    lines, inside = [], False
    for line in (ROOT / "README.md").read_text().splitlines():
        if line.startswith("```"):
            inside = line.strip() == "```bash" if not inside else False
            continue
        if inside and line.strip() and not line.lstrip().startswith("#"):
            lines.append(line.strip())
    return lines


def shrink(cmd: str, models: Path) -> str:
    """The same command on small sizes (see the module docstring)."""
    cmd = re.sub(r"\s+#.*$", "", cmd)  # the line's comment (none of the README's has '#' inside quotes)
    cmd = re.sub(r"^make demo\b", "signlane demo --out out/demo", cmd)
    cmd = re.sub(r"--n (\d+)", lambda m: f"--n {min(int(m.group(1)), 40)}", cmd)
    cmd = re.sub(r"--epochs \d+", "--epochs 1", cmd)
    cmd = re.sub(r"--seeds \d+", "--seeds 1", cmd)
    cmd = re.sub(r"\.venv/bin/python ", f"{sys.executable} ", cmd)
    parts = re.split(r"(\s*(?:&&|;|&)\s*)", cmd)  # each command of a line, with what joins them
    out = []
    for part in parts:
        p = part
        if re.match(r"\s*signlane (demo|sim)\b", p):
            p = re.sub(r"--max-seconds [\d.]+", "", p)  # the README's own length gives way to 4 s
            p = re.sub(r"(signlane (demo|sim)\b)", r"\1 --max-seconds 4 --size 320x240", p, count=1)
        if re.match(r"\s*signlane gen pilot\b", p):  # one seed per style, 8 s a drive: 3 split blocks each
            p = re.sub(r"--n \d+", "--n 1", re.sub(r"--seconds [\d.]+", "", p)) + " --seconds 8"
        if re.match(r"\s*signlane train pilot\b", p) and "--val-fraction" not in p:
            p += " --val-fraction 0.5"
        if re.match(r"\s*signlane train (signs|lanes|pilot)\b", p) and "--epochs" not in p:
            p = re.sub(r"(signlane train (signs|lanes|pilot))", r"\1 --epochs 1", p, count=1)
        if re.match(r"\s*signlane eval (lanes|proposals)\b", p):
            p = re.sub(r"(signlane eval (lanes|proposals))", r"\1 --n 4", p, count=1)
        if re.match(r"\s*signlane ship\b", p):
            p += f" --into {models}"
        if re.match(r"\s*\S+ benchmarks/(render|lanes|drive|pipeline|pilot)\.py", p):
            p += " --frames 3 --repeats 1" if "drive.py" not in p else " --frames 5 --repeats 1"
        if re.match(r"\s*\S+ benchmarks/signs\.py", p):
            p += " --repeats 1"
        out.append(p)
    return "".join(out)


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.pop("PYTHONPATH", None)
    return env


def _server_starts(cmd: str, cwd: Path) -> None:
    """A `signlane drive` line: it must come up listening; then Ctrl-C stops it cleanly."""
    proc = subprocess.Popen(["bash", "-c", f"exec {cmd}"], cwd=cwd, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    seen = []
    deadline = time.monotonic() + 120
    try:
        for line in proc.stdout:
            seen.append(line)
            if "listening on ws://" in line or time.monotonic() > deadline:
                break
        assert any("listening on ws://" in s for s in seen), f"{cmd}: never listened:\n{''.join(seen)}"
    finally:
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(timeout=60)
    assert rc in (0, 130), f"{cmd}: exit {rc} after Ctrl-C"


def test_every_readme_command_runs_in_order_on_a_fresh_folder(tmp_path):
    work = tmp_path / "clone"
    work.mkdir()
    for name in ("signlane", "benchmarks"):  # what the README's paths name in the repository
        (work / name).symlink_to(ROOT / name)
    (work / "out").mkdir()
    models = tmp_path / "models"
    models.mkdir()
    commands = [c for c in readme_commands() if not any(n in c for n in NOT_RUN)]
    assert len(commands) >= 30
    for cmd in commands:
        small = shrink(cmd, models)
        if re.match(r"signlane drive\b", small) and "&" not in small:
            _server_starts(small, work)
            continue
        done = subprocess.run(["bash", "-c", f"set -eo pipefail; {small}"], cwd=work, env=_env(),
                              capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"README command failed ({done.returncode}): {cmd}\nran: {small}\n" \
                                     f"{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert (models / "signs.onnx").exists() and (models / "lanes.onnx").exists()  # both recipes shipped
    assert (work / "out" / "demo" / "drive.mp4").exists() and (work / "out" / "signs_test" / "confusion.png").exists()
