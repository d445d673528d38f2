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


def test_config_print_is_toml_that_loads_back_to_the_same_config(tmp_path, capsys):
    from signlane.cli import main
    assert main(["config", "--print", "--set", "camera.pitch_deg=12.5", "--set", "lanes.method=road-edges"]) == 0
    text = capsys.readouterr().out
    assert "[camera]" in text and "pitch_deg = 12.5" in text and "# robust | published" in text
    path = tmp_path / "mine.toml"
    path.write_text(text)
    cfg = Config.load(path)
    assert cfg == Config.load(None, ["camera.pitch_deg=12.5", "lanes.method=road-edges"])
    assert cfg != Config()


def test_one_table_style_right_aligns_numbers_and_rejects_ragged_rows():
    from signlane.tables import pairs, table
    text = table(["method", "found %"], [["auto", "99.5"], ["sliding-window", "7.0"]]).splitlines()
    assert text[0] == "method          found %" and text[2].endswith("   99.5") and text[3].endswith("    7.0")
    assert table(["a", "b"], [["x", "1"]], markdown=True).splitlines() == ["| a | b |", "|---|---|", "| x | 1 |"]
    assert pairs([("laps", 1), ("off-road events", 0)]).splitlines() == ["laps             1", "off-road events  0"]
    with pytest.raises(ValueError, match="2 columns"):
        table(["a", "b"], [["only one"]])
