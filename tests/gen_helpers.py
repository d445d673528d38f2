"""Dataset-generation test helpers."""
import pytest

from signlane_data import lanes as lanes_mod


def generate_lanes_killed_at(out, kill_at: int, monkeypatch, n: int, **kw) -> None:
    """Run `generate_lanes` into `out` as if killed while making sample `kill_at` (the samples
    before it written, no manifest), then restore the generator."""
    real = lanes_mod.LaneJob.__call__

    def killed(self, i):
        if i == kill_at:
            raise RuntimeError("killed")
        real(self, i)
    monkeypatch.setattr(lanes_mod.LaneJob, "__call__", killed)
    with pytest.raises(RuntimeError, match="killed"):
        lanes_mod.generate_lanes(out, n, **kw)
    monkeypatch.setattr(lanes_mod.LaneJob, "__call__", real)
