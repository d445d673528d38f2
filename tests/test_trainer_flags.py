"""`signlane train`'s Lightning flags (read from the Trainer's signature) and its --config file."""
import pytest

pytest.importorskip("lightning")

from signlane.cli import main  # noqa: E402
from signlane.commands.trainer_flags import parse_value, trainer_parameters  # noqa: E402


def test_every_settable_trainer_argument_is_a_flag_and_values_are_checked_against_its_annotation():
    params = trainer_parameters()
    for name in ("accelerator", "devices", "precision", "gradient_clip_val", "accumulate_grad_batches", "max_time",
                 "limit_train_batches", "val_check_interval", "profiler", "fast_dev_run"):
        assert name in params
    assert not {"callbacks", "logger", "max_epochs", "default_root_dir"} & set(params)  # the run's own
    ann = {n: p.annotation for n, p in params.items()}
    assert parse_value("precision", "16", ann["precision"]) == 16
    assert parse_value("precision", "bf16-mixed", ann["precision"]) == "bf16-mixed"
    assert parse_value("max_time", "{hours = 1}", ann["max_time"]) == {"hours": 1}
    assert parse_value("devices", "[0, 1]", ann["devices"]) == [0, 1]
    assert parse_value("min_epochs", "none", ann["min_epochs"]) is None
    gv = parse_value("gradient_clip_val", "1", ann["gradient_clip_val"])
    assert gv == 1 and isinstance(gv, int)
    for name, text in (("precision", "17"), ("accumulate_grad_batches", "0.5"), ("num_nodes", "two"),
                       ("inference_mode", "3")):
        with pytest.raises(ValueError, match=f"trainer.{name}"):
            parse_value(name, text, ann[name])


def test_config_file_under_command_line_and_one_error_line_for_bad_keys(tmp_path, capsys):
    cfg = tmp_path / "t.toml"
    cfg.write_text('[train]\nepochs = 3\nlr = 0.001\ndata = ["a", "b"]\n[trainer]\nprecision = "bf16-mixed"\n')
    assert main(["train", "lanes", "--config", str(cfg), "--epochs", "5", "--accelerator", "cpu",
                 "--trainer.accumulate_grad_batches", "2", "--print-config"]) == 0
    out = capsys.readouterr().out
    assert "epochs = 5\n" in out and "lr = 0.001\n" in out and "batch_size = 32\n" in out  # flag, file, default
    assert 'precision = "bf16-mixed"' in out and 'accelerator = "cpu"' in out and "accumulate_grad_batches = 2" in out
    assert out.count("/a\"") == 1 and out.count("/b\"") == 1  # data from the file, absolute
    for text, what in (("[train]\nepoch = 3\n", "no option epoch"), ("[trainer]\nmax_epochs = 3\n", "--epochs"),
                       ("[trainer]\nlimit_batches = 3\n", "not a Lightning Trainer argument"),
                       ("[model]\nx = 1\n", "unknown table"), ("epochs = ", "not a TOML file")):
        cfg.write_text(text)
        assert main(["train", "signs", "x", "--config", str(cfg), "--print-config"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and what in err[0], err
    assert main(["train", "signs", "--print-config"]) == 2
    assert "no data folders" in capsys.readouterr().err
