"""Config: defaults, TOML, --set overrides and clear errors."""
import pytest

from signlane.config import Config


def test_defaults_toml_and_overrides(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text('[camera]\npitch_deg = 12\n[lanes]\nmethod = "canny-scan"\n')
    cfg = Config.load(f, ["camera.height_m=1.5", "signs.enabled=false", "lanes.variant=published"])
    assert cfg.camera.pitch_deg == 12.0 and cfg.camera.height_m == 1.5
    assert cfg.lanes.method == "canny-scan" and cfg.lanes.variant == "published"
    assert cfg.signs.enabled is False
    assert Config().camera.pitch_deg == 10.0  # defaults untouched
    assert cfg.to_dict()["camera"]["pitch_deg"] == 12.0


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
