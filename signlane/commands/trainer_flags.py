"""`signlane train`'s Lightning side: every `lightning.pytorch.Trainer` argument as a
`--trainer.NAME VALUE` flag, read from the Trainer's own signature (a newer Lightning brings its
new arguments without a change here), and the `--config FILE.toml` that sets any option.

Values are written as TOML values (`0.5`, `2`, `true`, `'bf16-mixed'`, `{hours = 1}`); a bare
word is a string. Each is checked against the argument's annotation, so a typo is one error line
before any data is read. The arguments a run owns are not flags: its checkpoints, logs, epochs
and determinism are part of the run folder's contract and have signlane options of their own.
"""
from __future__ import annotations

import argparse
import inspect
import tomllib
import types
import typing
from pathlib import Path

PREFIX = "trainer."
# the run folder's contract: which signlane option (or fixed part) stands for each
RUN_OWNED = {
    "callbacks": "the run's checkpoints and early stopping",
    "logger": "the run's CSV and TensorBoard logs",
    "default_root_dir": "--out",
    "max_epochs": "--epochs (the learning-rate schedule spans it)",
    "deterministic": "--deterministic/--no-deterministic",
    "enable_checkpointing": "the run's checkpoints (export and --resume read them)",
}
# the scale-out arguments keep their short spelling too
ALIASES = {"accelerator": "--accelerator", "devices": "--devices", "num_nodes": "--num-nodes",
           "strategy": "--strategy"}
SIMPLE = (bool, int, float, str, list, dict, type(None))


def trainer_parameters() -> dict[str, inspect.Parameter]:
    """The Trainer's arguments a command line can set (those with a plain-value alternative),
    or {} where Lightning is not installed (the runtime-only install)."""
    try:
        from lightning.pytorch import Trainer
    except ImportError:
        return {}
    params = {}
    for name, p in inspect.signature(Trainer.__init__).parameters.items():
        if name == "self" or name in RUN_OWNED or p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            continue
        if _allowed(p.annotation) - {type(None)}:
            params[name] = p
    return params


def _allowed(annotation) -> set:
    """The plain types and literal values an annotation accepts (classes that need objects: none)."""
    if annotation is inspect.Parameter.empty or annotation is typing.Any:
        return set(SIMPLE)
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        return set().union(*(_allowed(a) for a in typing.get_args(annotation)))
    if origin is typing.Literal:
        return {("literal", v) for v in typing.get_args(annotation)}
    if origin in (list, tuple) or annotation in (list, tuple):
        return {list}
    if origin is dict or annotation is dict:
        return {dict}
    if annotation is Path or getattr(annotation, "__name__", "") == "timedelta":
        return {str}  # a path, or a duration as Lightning's "DD:HH:MM:SS" string
    return {annotation} & set(SIMPLE)


def _describe(annotation) -> str:
    allowed = _allowed(annotation)
    names = sorted({a.__name__ if isinstance(a, type) else repr(a[1]) for a in allowed}, key=str)
    return " | ".join("none" if n == "NoneType" else n for n in names)


def parse_value(name: str, text, annotation):
    """A flag's or config file's value, checked against the argument's annotation. Text is read
    as a TOML value (a bare word: a string); `none`/`null` is None where that is allowed."""
    value = text
    if isinstance(text, str):
        if text.lower() in ("none", "null"):
            value = None
        else:
            try:
                value = tomllib.loads(f"v = {text}")["v"]
            except tomllib.TOMLDecodeError:
                value = text
    allowed = _allowed(annotation)
    literals = [a[1] for a in allowed if isinstance(a, tuple)]
    if any(type(value) is type(lit) and value == lit for lit in literals):
        return value
    if not isinstance(value, bool) and str(value) in literals:
        return str(value)  # 16 written for a literal '16'
    kind = type(value)
    if kind is bool:
        ok = bool in allowed
    elif kind is int:
        ok = int in allowed or float in allowed
        value = value if int in allowed else float(value)
    else:
        ok = kind in allowed
    if not ok:
        raise ValueError(f"trainer.{name}: {text!r} is not {_describe(annotation)}")
    return value


def add_trainer_flags(p: argparse.ArgumentParser) -> None:
    """--trainer.NAME for every settable Trainer argument (nothing where Lightning is absent)."""
    params = trainer_parameters()
    if not params:
        return
    g = p.add_argument_group("Lightning Trainer (every lightning.pytorch.Trainer argument; VALUE as TOML: "
                             "2, 0.5, true, bf16-mixed, {hours = 1})")
    for name, param in params.items():
        flags = [f"--{PREFIX}{name}"] + ([ALIASES[name]] if name in ALIASES else [])
        default = param.default if param.default is not inspect.Parameter.empty else None
        g.add_argument(*flags, dest=PREFIX + name, metavar="VALUE",
                       help=f"{_describe(param.annotation)} (Lightning's default {default!r})")
    g.set_defaults(_trainer_params=params)


def trainer_args(args: argparse.Namespace, from_file: dict) -> dict:
    """The Trainer arguments of a run: the config file's [trainer] table, then the flags given."""
    params = getattr(args, "_trainer_params", None) or trainer_parameters()
    out = {}
    for name, text in from_file.items():
        if name in RUN_OWNED:
            raise ValueError(f"[trainer] {name}: set by the run itself: use {RUN_OWNED[name]}")
        if name not in params:
            raise ValueError(f"[trainer] {name}: not a Lightning Trainer argument")
        out[name] = parse_value(name, text, params[name].annotation)
    for key, text in vars(args).items():
        if key.startswith(PREFIX) and text is not None:
            name = key[len(PREFIX):]
            out[name] = parse_value(name, text, params[name].annotation)
    return out


def read_train_config(path: Path | None) -> tuple[dict, dict]:
    """A training config file: its [train] table (signlane's options, by their long names with
    underscores) and its [trainer] table (Trainer arguments); ({}, {}) without a file."""
    if path is None:
        return {}, {}
    try:
        doc = tomllib.loads(Path(path).read_text())
    except OSError as e:
        raise ValueError(f"{path}: cannot read: {e.strerror or e}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not a TOML file: {e}") from None
    extra = set(doc) - {"train", "trainer"}
    if extra:
        raise ValueError(f"{path}: unknown table(s) {sorted(extra)}: a training config has [train] and [trainer]")
    for table in ("train", "trainer"):
        if not isinstance(doc.get(table, {}), dict):
            raise ValueError(f"{path}: {table} must be a table")
    return dict(doc.get("train", {})), dict(doc.get("trainer", {}))


def as_toml(train: dict, trainer: dict) -> str:
    """The resolved training options as a config file for --config."""
    from signlane.config import toml_value
    lines = ["[train]"] + [f"{k} = {toml_value(v)}" for k, v in train.items() if v is not None]
    lines += ["", "[trainer]"] + [f"{k} = {toml_value(v)}" for k, v in trainer.items() if v is not None]
    return "\n".join(lines) + "\n"
