"""`signlane train`, `export`, `ship`, `classify` and `autolabel`: the learned models."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from signlane.commands.common import UserError, add_config_args, load_config, positive


# --- train / export / classify --------------------------------------------------------------------
def add_train(sub, lightning_flags: bool = True) -> None:
    """lightning_flags: add a flag per Lightning Trainer argument (importing Lightning, which
    takes seconds: only when the command line is a `train` one)."""
    p = sub.add_parser("train", help="train the sign classifier or lane segmentation (needs the train extra)",
                       description="Train a model with Lightning on datasets from `signlane gen` (or autolabel). "
                                   "Writes checkpoints/ (best.ckpt, last.ckpt), logs/ (CSV), tensorboard/, "
                                   "config.json, train.toml (the resolved options: rerun with --config) and report "
                                   "pictures to --out. Resume a killed run with --resume.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs,lanes,pilot}")
    signs = kinds.add_parser("signs", help="the sign classifier on ImageFolder crops",
                             description="Train the sign classifier (a small CNN) on one or more ImageFolder crop "
                                         "sets; writes confusion.png and errors_<class>.png at the end. " + _CONFIG_HELP)
    _add_data_out(signs, "crop folders (<class>/<id>.png)")
    signs.add_argument("--epochs", type=positive, default=20, help="maximum epochs (default 20)")
    signs.add_argument("--batch-size", type=positive, default=128, help="batch size (default 128)")
    signs.add_argument("--lr", type=float, default=3e-3, help="peak learning rate (default 3e-3)")
    signs.add_argument("--size", type=int, choices=[32, 48], default=32, help="input size (default 32)")
    signs.add_argument("--width", type=int, default=16, help="channels of the first stage (default 16)")
    signs.add_argument("--class-weights", choices=["sqrt", "none"], default="sqrt",
                       help="loss weights: square-root inverse class frequency, or every crop alike (default sqrt)")
    signs.add_argument("--augment", type=float, default=1.0,
                       help="how often each training augmentation is applied, 0..1 (default 1; on generated "
                            "crops 0.5 scored no better)")
    _add_fit_args(signs, patience=6, workers=1, lightning_flags=lightning_flags)
    _add_train_lanes(kinds, lightning_flags)
    _add_train_pilot(kinds, lightning_flags)
    p.set_defaults(func=_run_train)


_CONFIG_HELP = ("Options come from the command line, else from --config FILE.toml ([train]: these options by "
                "their long names with underscores, data as a list; [trainer]: Lightning Trainer arguments), "
                "else the defaults.")


def _add_train_lanes(kinds, lightning_flags: bool) -> None:
    lanes = kinds.add_parser("lanes", help="the lane-marking segmentation net on lane datasets",
                             description="Train the lane-marking segmentation net (for `--lanes segnet`) on one or "
                                         "more lane datasets: `signlane gen lanes` output, `signlane autolabel lanes` "
                                         "output, or folders of images/ + masks/<stem>.png, mixed freely. Masks are "
                                         "read as the manifest's mask_encoding says (class ids 0/1 with 255 = "
                                         "ignore, left out of loss and metrics), binary 0/255 without one. Writes "
                                         "samples/epoch_<k>.png (truth green, prediction red) every epoch. "
                                         + _CONFIG_HELP)
    _add_data_out(lanes, "lane dataset folders")
    lanes.add_argument("--epochs", type=positive, default=15, help="maximum epochs (default 15)")
    lanes.add_argument("--batch-size", type=positive, default=32, help="batch size (default 32)")
    lanes.add_argument("--lr", type=float, default=4e-3, help="peak learning rate (default 4e-3)")
    lanes.add_argument("--width", type=positive, default=16, help="channels of the stem (default 16)")
    lanes.add_argument("--pos-weight", type=float, default=4.0,
                       help="cross-entropy weight of the marking class (default 4)")
    lanes.add_argument("--scene", action=argparse.BooleanOptionalAction, default=True,
                       help="frame-wide inputs and features: the frame's own contrast beside it at the stem, and "
                            "the whole frame's average features added back at 1/8 (default on; --no-scene "
                            "builds the net of models trained before it)")
    lanes.add_argument("--drivable-dice", type=float, default=0.5,
                       help="weight of the road surface's soft Dice loss beside its cross-entropy (a road model "
                            "only; default 0.5; 0 = cross-entropy alone, as before)")
    _add_fit_args(lanes, patience=5, workers=1, lightning_flags=lightning_flags)


def _add_train_pilot(kinds, lightning_flags: bool) -> None:
    pilot = kinds.add_parser("pilot", help="the end-to-end pilot on the teacher's drive recordings",
                             description="Train the end-to-end pilot (for `--set pilot.model=FILE`) on drive "
                                         "recordings: `signlane gen pilot` output, `signlane sim --record` or "
                                         "`signlane drive --record` folders, or folders holding several. The label "
                                         "is the teacher's own steering; --arch pilotnet is S3's PilotNet as "
                                         "published (HSV 120x160, conv 24/36/48 5x5 stride 2, conv 64/64 3x3, ELU, "
                                         "dropout 0.5, dense 100-50-10-1, MSE, Adam 1e-4, batch 100); --arch small "
                                         "is ours (HSV 96x72, one steering branch per desire left/straight/right, "
                                         "plus the teacher's target speed). Augmentation keeps the label true: a "
                                         "flipped frame negates steering and swaps left/right desire, a shift or a sideways move adds "
                                         "the steering back to the lane, roll and light leave it. Writes "
                                         "samples/epoch_<k>.png (val steering over time) every epoch. " + _CONFIG_HELP)
    _add_data_out(pilot, "recording folders")
    pilot.add_argument("--arch", choices=["pilotnet", "small"], default="small",
                       help="pilotnet (S3's, the baseline) or small (ours; default)")
    pilot.add_argument("--epochs", type=positive, default=15, help="maximum epochs (default 15)")
    pilot.add_argument("--batch-size", type=positive, default=None,
                       help="batch size (default: 100 for pilotnet as S3, 128 for small)")
    pilot.add_argument("--lr", type=float, default=None,
                       help="Adam learning rate, the peak with --schedule onecycle (default: 1e-4 pilotnet, 2e-3 small)")
    pilot.add_argument("--schedule", choices=["constant", "onecycle"], default=None,
                       help="learning rate over the run: constant (S3's, pilotnet's default) or onecycle (warm-up, "
                            "then annealed to near zero by the last epoch; small's default)")
    pilot.add_argument("--width", type=positive, default=16, help="channels of small's first conv (default 16)")
    pilot.add_argument("--speed-weight", type=float, default=0.1, help="small: weight of the speed loss (default 0.1)")
    pilot.add_argument("--flip", type=float, default=0.5, help="probability of a mirrored frame (default 0.5)")
    pilot.add_argument("--shift", type=float, default=0.08,
                       help="largest horizontal shift, a fraction of the width (relabelled; default 0.08; 0 = none)")
    pilot.add_argument("--lateral", type=float, default=0.6,
                       help="largest sideways move of the camera, metres: the road seen from beside the car's line, "
                            "relabelled with the pursuit's steering back (default 0.6; 0 = none)")
    pilot.add_argument("--balance", type=float, default=0.0,
                       help="draw frames weighted toward rare steering: (frames in the |steering| bin) ** -B, "
                            "0..1 (default 0, uniform; 1 = every bin alike)")
    pilot.add_argument("--no-augment", dest="augment", action="store_false", help="train on the frames as recorded")
    pilot.add_argument("--val-fraction", type=float, default=0.1,
                       help="share of 50-frame blocks of each drive held out for validation (default 0.1)")
    _add_fit_args(pilot, patience=5, workers=0, lightning_flags=lightning_flags)


def _add_data_out(p, what: str) -> None:
    p.add_argument("data", nargs="*", type=Path, help=what)
    p.add_argument("--out", type=Path, help="run folder (required, here or in the config file)")


def _add_fit_args(p, patience: int, workers: int, lightning_flags: bool) -> None:
    """What every training run takes: early stopping, the seed, CPU use and the run folder's options."""
    p.add_argument("--patience", type=positive, default=patience,
                   help=f"early-stopping patience in epochs (default {patience})")
    p.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    _add_cpu_args(p, workers=workers)
    _add_run_args(p, lightning_flags)


def _add_run_args(p, lightning_flags: bool) -> None:
    """--resume, --config, --print-config and the Trainer's flags; then every option's default is
    kept aside, so the config file can tell an option given from one left at its default."""
    from signlane.commands.trainer_flags import add_trainer_flags
    p.add_argument("--resume", action="store_true",
                   help="continue from --out/checkpoints/last.ckpt (saved after every epoch)")
    p.add_argument("--config", type=Path, help="training config file (TOML, [train] and [trainer] tables)")
    p.add_argument("--print-config", action="store_true",
                   help="print the resolved options as a config file (TOML) and exit without training")
    if lightning_flags:
        add_trainer_flags(p)
    defaults = {}
    for a in p._actions:
        if a.option_strings and a.dest not in ("help", "config", "print_config") and not a.dest.startswith("trainer."):
            defaults[a.dest] = a.default
            a.default = argparse.SUPPRESS
    p.set_defaults(_option_defaults=defaults)


def _add_cpu_args(p, workers: int) -> None:
    p.add_argument("--workers", type=int, default=workers,
                   help=f"data-loader worker processes: augmentation beside the training step (default {workers})")
    p.add_argument("--threads", type=int, default=0,
                   help="torch CPU threads (default 0 = torch's choice; 1 is fastest on a busy machine)")
    p.add_argument("--deterministic", action=argparse.BooleanOptionalAction, default=True,
                   help="deterministic torch algorithms (default on), so the same --seed repeats a run exactly; "
                        "--no-deterministic may be faster on GPUs (augmentations follow --seed either way)")


def _train_options(args) -> tuple[dict, dict]:
    """(signlane's options, Trainer arguments): the command line over the config file over the
    defaults; an unknown key or a bad value is one UserError line."""
    from signlane.commands.trainer_flags import read_train_config, trainer_args
    defaults = args._option_defaults
    try:
        file_train, file_trainer = read_train_config(args.config)
        unknown = sorted(set(file_train) - set(defaults) - {"data"})
        if unknown:
            raise ValueError(f"{args.config}: [train] has no option {', '.join(unknown)} "
                             f"(options: data, {', '.join(sorted(defaults))})")
        trainer = trainer_args(args, file_trainer)
    except ValueError as e:
        raise UserError(str(e)) from None
    given = {k: getattr(args, k) for k in defaults if hasattr(args, k)}
    opts = {**defaults, **file_train, **given}
    data = args.data or file_train.get("data") or []
    opts["data"] = [Path(d) for d in ([data] if isinstance(data, str) else data)]
    if not opts["data"]:
        raise UserError("no data folders: give them on the command line or as [train] data in --config")
    if opts.get("out") is None and not args.print_config:
        raise UserError("no run folder: give --out (or [train] out in --config)")
    opts["out"] = None if opts.get("out") is None else Path(opts["out"])
    return opts, trainer


def _run_train(args) -> int:
    from signlane.commands.trainer_flags import as_toml
    from signlane.fileio import atomic_write_text
    opts, trainer = _train_options(args)
    resolved = {k: [str(d.resolve()) for d in v] if k == "data" else (str(v.resolve()) if isinstance(v, Path) else v)
                for k, v in opts.items() if k != "resume"}
    if args.print_config:
        print(as_toml(resolved, trainer), end="")
        return 0
    try:
        from signlane_train.lanes import train_lanes
        from signlane_train.pilot import train_pilot
        from signlane_train.signs import train_signs
    except ImportError as e:
        raise UserError(f"training needs the train extra (pip install 'signlane[train]'): {e}") from None
    shared = {k: opts[k] for k in ("epochs", "batch_size", "lr", "width", "patience", "seed", "resume", "workers",
                                   "threads", "deterministic")}
    if args.kind == "pilot":
        from signlane_train.pilot_data import AugmentParams
        for k in ("flip", "shift"):
            if not 0 <= opts[k] <= 1:
                raise UserError(f"--{k} {opts[k]}: must be within 0..1")
        if not 0 <= opts["lateral"] <= 2:
            raise UserError(f"--lateral {opts['lateral']}: must be within 0..2 metres")
        aug = (AugmentParams(flip=opts["flip"], shift=opts["shift"], lateral_m=opts["lateral"])
               if opts["augment"] else None)
        if not 0 < opts["val_fraction"] < 1:
            raise UserError(f"--val-fraction {opts['val_fraction']}: must be between 0 and 1")
        if not 0 <= opts["balance"] <= 1:
            raise UserError(f"--balance {opts['balance']}: must be within 0..1")
        train, own = train_pilot, dict(arch=opts["arch"], speed_weight=opts["speed_weight"], augment=aug,
                                       val_fraction=opts["val_fraction"], balance=opts["balance"],
                                       schedule=opts["schedule"])
    elif args.kind == "lanes":
        if opts["drivable_dice"] < 0:
            raise UserError(f"--drivable-dice {opts['drivable_dice']}: must be >= 0")
        train, own = train_lanes, dict(pos_weight=opts["pos_weight"], scene=opts["scene"],
                                       drivable_dice=opts["drivable_dice"])
    else:
        train, own = train_signs, dict(size=opts["size"], class_weights=opts["class_weights"], augment=opts["augment"])
    opts["out"].mkdir(parents=True, exist_ok=True)
    atomic_write_text(opts["out"] / "train.toml", as_toml(resolved, trainer))  # this run, as a --config
    from lightning.fabric.utilities.exceptions import MisconfigurationException
    try:
        report = train(opts["data"], opts["out"], trainer_args=trainer, **shared, **own)
    except (ValueError, MisconfigurationException) as e:  # e.g. a Trainer argument this data cannot take
        raise UserError((str(e).strip().splitlines() or [type(e).__name__])[0]) from None
    report.pop("confusion", None)  # a matrix: confusion.png shows it
    print(json.dumps(report, indent=1))
    return 0


def add_export(sub) -> None:
    p = sub.add_parser("export", help="export a checkpoint to ONNX with its contract (needs the train extra)",
                       description="Export a trained checkpoint to ONNX with the model contract in its metadata, "
                                   "check it with onnx.checker and compare onnxruntime with torch on fixed inputs "
                                   "(max abs diff <= 1e-4) or fail.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs,lanes,pilot}")
    signs = kinds.add_parser("signs", help="the sign classifier")
    signs.add_argument("ckpt", type=Path, help="checkpoint (e.g. RUN/checkpoints/best.ckpt)")
    signs.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    signs.add_argument("--int8", action="store_true", help="also write <out>_int8.onnx and report its accuracy drop")
    lanes = kinds.add_parser("lanes", help="the lane-marking segmentation net (for --lanes segnet)")
    lanes.add_argument("ckpt", type=Path, help="checkpoint (e.g. RUN/checkpoints/best.ckpt)")
    lanes.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    pilot = kinds.add_parser("pilot", help="the end-to-end pilot (for --set pilot.model=FILE)")
    pilot.add_argument("ckpt", type=Path, help="checkpoint (e.g. RUN/checkpoints/best.ckpt)")
    pilot.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    p.set_defaults(func=_run_export)


def _refuse_models_dir(out: Path, command: str, kind: str) -> None:
    """A model written straight into the package's models folder would, with an editable install,
    be what every later command uses, unasked: `signlane ship` is the step that does that."""
    from signlane.ship import in_models_dir
    if in_models_dir(out):
        raise UserError(f"--out {out}: {command} does not write into the shipped models' folder; write to "
                        f"runs/ or out/, then `signlane ship FILE.onnx --as {kind}`")


def _run_export(args) -> int:
    _refuse_models_dir(args.out, "export", args.kind)
    if args.kind in ("lanes", "pilot"):
        return _run_export_lanes(args)
    try:
        from signlane_export.onnx_export import ExportError
        from signlane_export.signs import export_signs
    except ImportError as e:
        raise UserError(f"export needs the train extra (pip install 'signlane[train]'): {e}") from None
    try:
        report = export_signs(args.ckpt, args.out, int8=args.int8)
    except (ValueError, OSError, ExportError) as e:
        raise UserError(str(e)) from None
    print(json.dumps(report, indent=1))
    return 0


def _run_export_lanes(args) -> int:
    """export lanes / export pilot: a checkpoint in, one ONNX file out."""
    from signlane.onnx_model import ModelError
    try:
        from signlane_export.lanes import export_lanes
        from signlane_export.onnx_export import ExportError
        from signlane_export.pilot import export_pilot
    except ImportError as e:
        raise UserError(f"export needs the train extra (pip install 'signlane[train]'): {e}") from None
    try:
        report = (export_pilot if args.kind == "pilot" else export_lanes)(args.ckpt, args.out)
    except (ValueError, OSError, ExportError, ModelError) as e:
        raise UserError(str(e)) from None
    print(json.dumps(report, indent=1))
    return 0


def add_quantize(sub) -> None:
    p = sub.add_parser("quantize", help="an exported model as int8, for a faster CPU runtime (needs the train extra)",
                       description="Static int8 quantization (QDQ, per-channel weights) of an exported fp32 model, "
                                   "calibrated on the val crops of a dataset made as its training data was (its own, "
                                   "or `signlane gen signs` with another seed). Prints both files' accuracy on those "
                                   "crops and how often their labels agree; ship the int8 file only if it keeps the "
                                   "accuracy (check it with `signlane eval signs` on a fresh set).",
                       epilog="example: signlane quantize signs signlane/models/signs.onnx --data data/signs "
                              "--out runs/signs_int8/signs.onnx")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs}")
    signs = kinds.add_parser("signs", help="the sign classifier (about 3x faster per crop on one thread)")
    signs.add_argument("model", type=Path, help="exported fp32 ONNX sign classifier (e.g. runs/signs/signs.onnx)")
    signs.add_argument("--data", type=Path, nargs="+", required=True,
                       help="crop set(s) (<class>/<id>.png, as `signlane gen signs` writes): calibrated on their val split")
    signs.add_argument("--out", type=Path, required=True, help="int8 ONNX file to write")
    p.set_defaults(func=_run_quantize)


def _run_quantize(args) -> int:
    from signlane.onnx_model import ModelError
    _refuse_models_dir(args.out, "quantize", args.kind)
    try:
        from signlane_export.onnx_export import ExportError
        from signlane_export.signs import quantize_signs
    except ImportError as e:
        raise UserError(f"quantize needs the train extra (pip install 'signlane[train]'): {e}") from None
    args.out.parent.mkdir(parents=True, exist_ok=True)
    try:
        report = quantize_signs(args.model, args.data, args.out)
    except (ValueError, OSError, ExportError, ModelError) as e:
        raise UserError(str(e)) from None
    print(json.dumps(report, indent=1))
    return 0


def add_ship(sub) -> None:
    p = sub.add_parser("ship", help="make an exported model the default one (signlane/models/)",
                       description="Check an exported ONNX model as the runtime loads it (contract, graph, a test "
                                   "batch) and copy it over the shipped default, signlane/models/<kind>.onnx, that "
                                   "infer, drive, sim and demo use. Recipes never write there themselves. The model "
                                   "card beside it (<kind>.json) is rewritten for the shipped file, keeping the "
                                   "card it replaces under 'replaced'.")
    p.add_argument("model", type=Path, help="exported ONNX file (e.g. runs/signs/signs.onnx)")
    p.add_argument("--as", dest="kind", required=True, choices=["signs", "lanes", "pilot"],
                   help="which default it replaces")
    p.add_argument("--into", type=Path, help="models folder (default: the package's signlane/models)")
    p.set_defaults(func=_run_ship)


def _run_ship(args) -> int:
    from signlane.ship import MODELS_DIR, ShipError, ship_model
    try:
        report = ship_model(args.model, args.kind, args.into or MODELS_DIR)
    except (ShipError, OSError) as e:
        raise UserError(str(e)) from None
    print(json.dumps(report, indent=1))
    return 0


def add_classify(sub) -> None:
    p = sub.add_parser("classify", help="classify sign crops with the ONNX sign classifier",
                       description="Classify image crops of signs; prints one JSON object per crop: "
                                   '{"source", "label", "score", "scores": {label: p}}.')
    p.add_argument("crops", nargs="+", help="crop images (or folders of them)")
    p.add_argument("--model", type=Path, help="ONNX model (default: the shipped signlane/models/signs.onnx)")
    p.set_defaults(func=_run_classify)


def _run_classify(args) -> int:
    from signlane.media import MediaError, expand, read_image
    from signlane.onnx_model import ModelError
    from signlane.signs.classifier import DEFAULT_MODEL, SignClassifier
    try:
        clf = SignClassifier(args.model or DEFAULT_MODEL)
    except ModelError as e:
        raise UserError(str(e)) from None
    sources, errors = expand(args.crops)
    for e in errors:
        print(f"signlane classify: {e}", file=sys.stderr)
    failed = len(errors)
    for src in sources:
        try:
            img = read_image(src.path)
        except MediaError as e:
            print(f"signlane classify: {e}", file=sys.stderr)
            failed += 1
            continue
        label, score, scores = clf.classify([img])[0]
        print(json.dumps({"source": str(src.path), "label": label, "score": round(score, 5),
                          "scores": {k: round(v, 5) for k, v in scores.items()}}))
    return 1 if failed else 0


# --- autolabel ---------------------------------------------------------------------------------
def add_autolabel(sub) -> None:
    p = sub.add_parser("autolabel", help="label your own images with the classical stages + current models",
                       description="Turn your own images and videos into a reviewable training set.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs,lanes}")
    signs = kinds.add_parser("signs", help="sign crops foldered by the classifier (review, then train on them)",
                             description="Run the colour-mask proposals and the current sign classifier on "
                                         "your images/videos; write each proposal's crop to <out>/<label>/ "
                                         "(ImageFolder) and a contact sheet per class (sheet_<label>.png). Move "
                                         "wrong crops to the right folder, then `signlane train signs` on it.")
    signs.add_argument("paths", nargs="+", help="images, videos or folders")
    signs.add_argument("--out", type=Path, required=True, help="output folder")
    signs.add_argument("--model", type=Path, help="classifier ONNX (default: the shipped one, if present)")
    signs.add_argument("--every", type=positive, default=10, help="every Nth video frame (default 10)")
    signs.add_argument("--size", type=positive, default=48, help="crop size in pixels (default 48)")
    _add_autolabel_lanes(kinds)
    p.set_defaults(func=_run_autolabel)


def _add_autolabel_lanes(kinds) -> None:
    lanes = kinds.add_parser("lanes", help="pseudo-labelled lane masks from a lane method's confident frames",
                             description="Run a lane method on your images/videos and keep only the frames it is "
                                         "confident about, as a lane dataset (images/, masks/, labels.jsonl, "
                                         "manifest.json) that `signlane train lanes` can mix with synthetic sets; "
                                         "sheet.png shows the kept frames, rejected.png some dropped ones. Masks are "
                                         "class ids: 1 on the paint the method followed, 0 around it, 255 (ignore) "
                                         "on the rows beyond the farthest paint it labelled.")
    lanes.add_argument("paths", nargs="+", help="images, videos or folders")
    lanes.add_argument("--out", type=Path, required=True, help="output folder (new or empty)")
    lanes.add_argument("--method", default="sliding-window", help="lane method (default sliding-window)")
    lanes.add_argument("--min-confidence", type=float, default=0.7,
                       help="keep frames whose lane confidence reaches this (default 0.7); keeping none is "
                            "exit code 1")
    lanes.add_argument("--every", type=positive, default=10, help="every Nth video frame (default 10)")
    add_config_args(lanes, "TOML config file (the camera section matters)")


def _run_autolabel(args) -> int:
    if args.kind == "lanes":
        return _run_autolabel_lanes(args)
    from signlane.autolabel import autolabel_signs
    from signlane.onnx_model import ModelError
    try:
        report = autolabel_signs(args.paths, args.out, args.model, args.every, args.size)
    except ModelError as e:
        raise UserError(str(e)) from None
    print(json.dumps({"out": str(args.out), "counts": report["counts"], "model": report["model"]}))
    return 1 if report["failed"] else 0


def _run_autolabel_lanes(args) -> int:
    from signlane_data.autolabel_lanes import autolabel_lanes
    from signlane_data.common import DatasetError
    from signlane.onnx_model import ModelError
    cfg = load_config(args)
    try:
        report = autolabel_lanes(args.paths, args.out, args.method, cfg.camera, args.min_confidence, args.every)
    except (ValueError, ModelError, DatasetError) as e:
        raise UserError(str(e)) from None
    print(json.dumps({"out": str(args.out), "counts": report["counts"], "method": args.method}))
    if report["counts"]["kept"] == 0:  # an empty set must not pass for a dataset: say so, exit 1
        print(f"signlane autolabel: kept none of the {report['counts']['seen']} frames (no lane found with "
              f"confidence >= {args.min_confidence}); {args.out} is no training set: see "
              f"{args.out / 'rejected.png'}, check the camera (--set camera.*) or lower --min-confidence",
              file=sys.stderr)
        return 1
    return 1 if report["failed"] else 0
