"""Config: defaults, TOML, --set overrides and clear errors."""
import math
from dataclasses import replace

import pytest

from signlane.camera import via_camera
from signlane.config import Config


def test_defaults_toml_and_overrides(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text('[camera]\npitch_deg = 12\n[lanes]\nmethod = "canny-scan"\n')
    cfg = Config.load(f, ["camera.height_m=1.5", "signs.enabled=false", "lanes.variant=published"])
    assert cfg.camera.pitch_deg == 12.0 and cfg.camera.height_m == 1.5
    assert cfg.lanes.method == "canny-scan" and cfg.lanes.variant == "published"
    assert cfg.signs.enabled is False
    assert cfg.camera.hfov_deg == Config().camera.hfov_deg  # what the file and --set leave alone
    assert cfg.to_dict()["camera"]["pitch_deg"] == 12.0
    # defaults untouched by loading: VIA's camera (60 degrees vertical at 4:3, in effect 2.9 m
    # up at 11.8 degrees) and the lane method that tells kerbed and painted roads apart
    d = Config()
    assert (d.camera.height_m, d.camera.pitch_deg, d.camera.roll_deg) == (2.9, 11.8, 0.0)
    assert d.camera.hfov_deg == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(30)) * 4 / 3)), abs=0.01)
    assert d.camera.camera(640, 480).focal_px == pytest.approx(240 / math.tan(math.radians(30)), rel=1e-3)
    assert d.camera.camera(640, 480) == replace(via_camera(640, 480), hfov_deg=d.camera.hfov_deg)
    assert (d.lanes.method, d.lanes.variant) == ("auto", "robust")


@pytest.mark.parametrize("override,match", [("camera.zoom=2", "unknown setting 'zoom'"),
                                            ("camera.pitch_deg=steep", "not a float"),
                                            ("signs.enabled=3", "not a bool"),
                                            ("camera=3", "is a section"),
                                            ("nokey", "expected section.key=value")])
def test_bad_overrides_name_the_problem(override, match):
    with pytest.raises(ValueError, match=match):
        Config.load(None, [override])


def test_bad_toml_file(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("[camera\n")
    with pytest.raises(ValueError, match="invalid TOML"):
        Config.load(f)
    with pytest.raises(ValueError, match="cannot read"):
        Config.load(tmp_path / "none.toml")
