"""`signlane <subcommand>`: thin argument parsing; each subcommand calls one library function.

Heavy imports stay inside the subcommand that needs them, so `signlane --help` is instant.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from signlane import __version__

log = logging.getLogger("signlane")


class UserError(Exception):
    """A problem with the user's input: printed as one line, exit code 2."""


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
        return w, h
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 320x240 (both >= 16), not {text!r}") from None


def _positive(text: str) -> int:
    v = int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, not {v}")
    return v


# --- gen ---------------------------------------------------------------------------------------
def _add_gen(sub) -> None:
    p = sub.add_parser("gen", help="generate synthetic datasets (lanes, signs, drive)",
                       description="Generate seeded synthetic datasets from the world renderer. The same "
                                   "seed gives the same files whatever --workers; an interrupted run is "
                                   "completed with --resume.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{lanes,signs,drive}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--n", type=_positive, required=True, help="number of frames / crops")
    common.add_argument("--out", type=Path, required=True, help="output folder")
    common.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    common.add_argument("--resume", action="store_true", help="complete an interrupted run in --out")
    common.add_argument("--preview", action="store_true", help="also write contact sheets (preview*.png)")
    lanes = kinds.add_parser("lanes", parents=[common], help="frames + lane-marking masks + labels.jsonl",
                             description="Frames with exact lane-marking masks and labels (images/, masks/, "
                                         "labels.jsonl, manifest.json).")
    lanes.add_argument("--size", type=_size, default=(320, 240), help="frame size WxH (default 320x240)")
    lanes.add_argument("--workers", type=_positive, default=1, help="worker processes (default 1)")
    lanes.add_argument("--effects", choices=["clean", "normal", "hard", "mixed"], default="mixed",
                       help="photometric/pose randomisation (default mixed: normal and hard)")
    lanes.add_argument("--no-randomise", dest="randomise", action="store_false",
                       help="default road style, looks and camera instead of randomised ones")
    signs = kinds.add_parser("signs", parents=[common], help="labelled sign crops (ImageFolder)",
                             description="Sign crops in ImageFolder layout <class>/<id>.png with VIA class "
                                         "names, including 'unknown' crops of red/blue non-signs.")
    signs.add_argument("--crop", type=_positive, default=48, help="crop size in pixels (default 48)")
    signs.add_argument("--workers", type=_positive, default=1, help="worker processes (default 1)")
    drive = kinds.add_parser("drive", parents=[common], help="a frame sequence along one track (+ drive.mp4)",
                             description="Consecutive frames along one seeded track, in the lanes layout, "
                                         "plus drive.mp4.")
    drive.add_argument("--size", type=_size, default=(640, 480), help="frame size WxH (default 640x480)")
    drive.add_argument("--fps", type=float, default=20.0, help="frames per second of the drive (default 20)")
    p.set_defaults(func=_run_gen)


def _run_gen(args) -> int:
    from data_gen.common import DatasetError
    try:
        return _gen(args)
    except DatasetError as e:
        raise UserError(str(e)) from None


def _gen(args) -> int:
    if args.kind == "lanes":
        from data_gen.lanes import generate_lanes
        m = generate_lanes(args.out, args.n, args.seed, width=args.size[0], height=args.size[1],
                           workers=args.workers, resume=args.resume, preview=args.preview,
                           effects=args.effects, randomise=args.randomise)
    elif args.kind == "signs":
        from data_gen.signs import generate_signs
        m = generate_signs(args.out, args.n, args.seed, crop=args.crop, workers=args.workers,
                           resume=args.resume, preview=args.preview)
    else:
        from data_gen.drive import generate_drive
        m = generate_drive(args.out, args.n, args.seed, width=args.size[0], height=args.size[1], fps=args.fps,
                           resume=args.resume, preview=args.preview)
    print(json.dumps({"out": str(args.out), "counts": m.get("counts")}))
    return 0


# --- demo --------------------------------------------------------------------------------------
def _add_demo(sub) -> None:
    p = sub.add_parser("demo", help="render a short drive to an MP4, a contact sheet and a track map",
                       description="Render a short drive on the bundled loop_demo map (or a seeded procedural "
                                   "track with --track random): drive.mp4 (camera view and ground truth side by "
                                   "side), contact_sheet.png and track.png.")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default out/demo)")
    p.add_argument("--track", default="loop_demo",
                   help="'loop_demo' (bundled, default), 'random' (procedural, see --seed) or a VIA map JSON file")
    p.add_argument("--seed", type=int, default=0, help="seed of the route's choices and a random track (default 0)")
    p.add_argument("--seconds", type=float, default=20.0, help="length of the drive (default 20)")
    p.add_argument("--size", type=_size, default=(640, 480), help="frame size WxH (default 640x480)")
    p.set_defaults(func=_run_demo)


def _run_demo(args) -> int:
    from signlane.demo import bundled_map, run_demo
    from signlane.world.procedural import generate_map
    from signlane.world.track import MapError, Track
    try:
        if args.track == "loop_demo":
            track = bundled_map()
        elif args.track == "random":
            track = Track.from_via(generate_map(args.seed))
        else:
            track = Track.load(args.track)
    except MapError as e:
        raise UserError(str(e)) from None
    res = run_demo(args.out, seed=args.seed, seconds=args.seconds, width=args.size[0], height=args.size[1],
                   track=track)
    for name, path in res["files"].items():
        print(f"{name:>14}: {path}")
    return 0


# --- map ---------------------------------------------------------------------------------------
def _add_map(sub) -> None:
    p = sub.add_parser("map", help="check a VIA map file, or make a procedural one; draw it from above",
                       description="Load a VIA map JSON (or generate a seeded procedural map), check that every "
                                   "road connects, print a summary and optionally write a top-down PNG and "
                                   "the map JSON.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("file", nargs="?", type=Path, help="VIA map JSON file")
    src.add_argument("--random", type=int, metavar="SEED", help="generate a procedural map with this seed")
    p.add_argument("--size", choices=["small", "medium", "large"], default="medium",
                   help="procedural map size (default medium)")
    p.add_argument("--png", type=Path, help="write a top-down picture here")
    p.add_argument("--save", type=Path, help="write the map JSON here (for --random)")
    p.set_defaults(func=_run_map)


def _run_map(args) -> int:
    from signlane.world.procedural import generate_map
    from signlane.world.route import Route
    from signlane.world.scene import build_scene
    from signlane.world.topdown import draw_topdown
    from signlane.world.track import MapError, Track
    from signlane.draw import write_image
    try:
        if args.file is not None:
            track = Track.load(args.file)
            data = None
        else:
            data = generate_map(args.random, size=args.size)
            track = Track.from_via(data)
    except MapError as e:
        raise UserError(str(e)) from None
    kinds: dict[str, int] = {}
    for t in track.tiles:
        kinds[t.name] = kinds.get(t.name, 0) + 1
    lap = Route.loop(track)
    print(json.dumps({"name": track.name, "grid": [track.cols, track.rows], "tiles": kinds,
                      "signs": [s.kind for s in track.signs], "lap_m": round(lap.length, 1)}))
    if args.png:
        write_image(args.png, draw_topdown(build_scene(track), path_xy=lap.lane))
    if args.save and data is not None:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        args.save.write_text(json.dumps(data, indent=1))
    return 0


# --- infer -------------------------------------------------------------------------------------
def _add_config_args(p) -> None:
    p.add_argument("--config", type=Path, help="TOML config file (sections camera, lanes, signs, control)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting, e.g. --set camera.pitch_deg=12 (repeatable)")


def _config(args):
    from signlane.config import Config
    try:
        cfg = Config.load(args.config, args.overrides)
    except ValueError as e:
        raise UserError(str(e)) from None
    lanes_method = getattr(args, "lanes", None)
    if lanes_method:
        from dataclasses import replace
        cfg = replace(cfg, lanes=replace(cfg.lanes, method=lanes_method))
    return cfg


def _add_infer(sub) -> None:
    p = sub.add_parser("infer", help="run the pipeline on images, folders and videos",
                       description="Run lane detection, sign proposals and steering on images, folders of "
                                   "images/videos, and video files. Writes annotated images/videos with --out and "
                                   "one JSON object per frame with --json FILE ('-' for stdout). A bad input gets "
                                   "one error line; the rest still runs; the exit code is 1 if any input failed.")
    p.add_argument("paths", nargs="+", help="image files, video files or folders")
    p.add_argument("--out", type=Path, help="folder for annotated images/videos (and masks)")
    p.add_argument("--json", dest="json_path", metavar="FILE", help="write per-frame JSON lines here ('-' = stdout)")
    p.add_argument("--lanes", metavar="METHOD",
                   help="lane method: canny-scan, sliding-window, color-hough, vector-spline (default from config)")
    p.add_argument("--save-masks", action="store_true", help="write <stem>_lane.png (0/255) beside each annotated image")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bars")
    _add_config_args(p)
    p.set_defaults(func=_run_infer)


def _run_infer(args) -> int:
    from signlane.infer import run_infer
    from signlane.onnx_model import ModelError
    cfg = _config(args)
    try:
        summary = run_infer(args.paths, cfg, out=args.out, json_path=args.json_path, save_masks=args.save_masks,
                            progress=args.progress)
    except (ValueError, ModelError) as e:
        raise UserError(str(e)) from None
    print(summary.table(), file=sys.stderr)
    return 1 if summary.failed else 0


# --- eval --------------------------------------------------------------------------------------
def _add_eval(sub) -> None:
    p = sub.add_parser("eval", help="score lane methods or sign proposals on a seeded synthetic test set",
                       description="Render a seeded synthetic test set and print a score table.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{lanes,proposals,signs}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--n", type=_positive, default=500, help="frames (default 500)")
    common.add_argument("--seed", type=int, default=1000, help="test-set seed (default 1000)")
    common.add_argument("--hard", action="store_true", help="the hard set: glare, blur, noise, worn paint, shadows")
    common.add_argument("--variant", choices=["robust", "published", "both"], default="robust",
                        help="robust (default), the source's published baseline, or both")
    common.add_argument("--csv", type=Path, help="also write the table as CSV")
    common.add_argument("--plot", type=Path, help="also write a PNG plot")
    lanes = kinds.add_parser("lanes", parents=[common], help="lane found %%, offset/heading errors, curvature sign",
                             description="Lane found %, median and 95th percentile lateral-offset error (fraction "
                                         "of lane width), heading error, curvature sign agreement, ms/frame.")
    lanes.add_argument("--method", action="append", help="lane method (repeatable; default: all available)")
    lanes.add_argument("--size", type=_size, default=(320, 240), help="frame size WxH (default 320x240)")
    prop = kinds.add_parser("proposals", parents=[common], help="recall of signs >= 20 px and false proposals/frame",
                            description="Recall of ground-truth signs (box IoU >= 0.5, signs >= --min-size px) and "
                                        "false proposals per frame.")
    prop.add_argument("--min-size", type=int, default=20, help="smallest sign side counted, px (default 20)")
    prop.add_argument("--size", type=_size, default=(640, 480), help="frame size WxH (default 640x480)")
    prop.add_argument("--focus", choices=["signs", "none"], default="signs",
                      help="signs (default): each frame 4-45 m before a sign, so the set holds enough signs; "
                           "none: anywhere on the track")
    signs = kinds.add_parser("signs", help="sign classifier accuracy on a crop set",
                             description="Accuracy, per-class recall and non-sign acceptance of the ONNX sign "
                                         "classifier on an ImageFolder crop set (make a fresh one with "
                                         "`signlane gen signs --seed S`).")
    signs.add_argument("data", type=Path, help="crop folder (<class>/<id>.png)")
    signs.add_argument("--model", type=Path, help="ONNX model (default: the shipped one)")
    signs.add_argument("--min-score", type=float, default=0.5, help="score a sign needs to count (default 0.5)")
    p.set_defaults(func=_run_eval)


def _run_eval(args) -> int:
    if args.kind == "signs":
        from signlane.evaluate import eval_signs
        from signlane.onnx_model import ModelError
        try:
            print(json.dumps(eval_signs(args.data, args.model, args.min_score), indent=1))
        except (ModelError, ValueError, OSError) as e:
            raise UserError(str(e)) from None
        return 0
    variants = ["robust", "published"] if args.variant == "both" else [args.variant]
    if args.kind == "lanes":
        from signlane import lanes
        from signlane.evaluate import eval_lanes, format_table, plot_lanes, write_csv
        methods = args.method or lanes.available()
        try:
            rows = [eval_lanes(m, args.n, args.seed, args.hard, v, *args.size) for m in methods for v in variants]
        except ValueError as e:
            raise UserError(str(e)) from None
        print(format_table(rows))
        if args.csv:
            write_csv(args.csv, rows)
        if args.plot:
            plot_lanes(args.plot, rows)
        return 0
    from signlane.draw import write_image
    from signlane.signs import eval_proposals as ep
    rows = ep.eval_many(args.n, args.seed, args.hard, variants, args.min_size, *args.size, progress=True,
                        focus=args.focus)
    print(ep.format_table(rows))
    if args.csv:
        ep.write_csv(args.csv, rows)
    if args.plot:
        write_image(args.plot, ep.plot_recall_by_size(rows))
    return 0


# --- train / export / classify --------------------------------------------------------------------
def _add_scale_out(p) -> None:
    g = p.add_argument_group("scale-out (passed to Lightning)")
    g.add_argument("--accelerator", default="auto", help="cpu, gpu, auto (default auto)")
    g.add_argument("--devices", default="auto", help="number of devices or 'auto' (default auto)")
    g.add_argument("--num-nodes", type=int, default=1, help="machines (default 1)")
    g.add_argument("--strategy", default="auto", help="e.g. ddp (default auto)")


def _add_train(sub) -> None:
    p = sub.add_parser("train", help="train the sign classifier (needs the train extra)",
                       description="Train a model with Lightning on datasets from `signlane gen` (or autolabel). "
                                   "Writes checkpoints/ (best.ckpt, last.ckpt), logs/ (CSV), tensorboard/, "
                                   "config.json and report pictures to --out. Resume a killed run with --resume.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs}")
    signs = kinds.add_parser("signs", help="the sign classifier on ImageFolder crops",
                             description="Train the sign classifier (a small CNN) on one or more ImageFolder crop "
                                         "sets; writes confusion.png and errors_<class>.png at the end.")
    signs.add_argument("data", nargs="+", type=Path, help="crop folders (<class>/<id>.png)")
    signs.add_argument("--out", type=Path, required=True, help="run folder")
    signs.add_argument("--epochs", type=_positive, default=20, help="maximum epochs (default 20)")
    signs.add_argument("--batch-size", type=_positive, default=128, help="batch size (default 128)")
    signs.add_argument("--lr", type=float, default=3e-3, help="peak learning rate (default 3e-3)")
    signs.add_argument("--size", type=int, choices=[32, 48], default=32, help="input size (default 32)")
    signs.add_argument("--patience", type=_positive, default=6, help="early-stopping patience in epochs (default 6)")
    signs.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    signs.add_argument("--workers", type=int, default=0, help="data-loader worker processes (default 0)")
    signs.add_argument("--resume", action="store_true", help="continue from --out/checkpoints/last.ckpt")
    _add_scale_out(signs)
    p.set_defaults(func=_run_train)


def _run_train(args) -> int:
    try:
        from train.common import ScaleOut
        from train.signs import train_signs
    except ImportError as e:
        raise UserError(f"training needs the train extra (pip install 'signlane[train]'): {e}") from None
    scale = ScaleOut(args.accelerator, args.devices, args.num_nodes, args.strategy)
    try:
        report = train_signs(args.data, args.out, epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                             size=args.size, patience=args.patience, seed=args.seed, resume=args.resume,
                             scale=scale, workers=args.workers)
    except ValueError as e:
        raise UserError(str(e)) from None
    report.pop("confusion", None)
    print(json.dumps(report, indent=1))
    return 0


def _add_export(sub) -> None:
    p = sub.add_parser("export", help="export a checkpoint to ONNX with its contract (needs the train extra)",
                       description="Export a trained checkpoint to ONNX with the model contract in its metadata, "
                                   "check it with onnx.checker and compare onnxruntime with torch on fixed inputs "
                                   "(max abs diff <= 1e-4) or fail.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs}")
    signs = kinds.add_parser("signs", help="the sign classifier")
    signs.add_argument("ckpt", type=Path, help="checkpoint (e.g. RUN/checkpoints/best.ckpt)")
    signs.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    signs.add_argument("--int8", action="store_true", help="also write <out>_int8.onnx and report its accuracy drop")
    p.set_defaults(func=_run_export)


def _run_export(args) -> int:
    try:
        from export.signs import export_signs
    except ImportError as e:
        raise UserError(f"export needs the train extra (pip install 'signlane[train]'): {e}") from None
    try:
        report = export_signs(args.ckpt, args.out, int8=args.int8)
    except (ValueError, OSError) as e:
        raise UserError(str(e)) from None
    print(json.dumps(report, indent=1))
    return 0


def _add_classify(sub) -> None:
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
def _add_autolabel(sub) -> None:
    p = sub.add_parser("autolabel", help="label your own images with the classical stages + current models",
                       description="Turn your own images and videos into a reviewable training set.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{signs}")
    signs = kinds.add_parser("signs", help="sign crops foldered by the classifier (review, then train on them)",
                             description="Run the colour-mask proposals and the current sign classifier on "
                                         "your images/videos; write each proposal's crop to <out>/<label>/ "
                                         "(ImageFolder) and a contact sheet per class (sheet_<label>.png). Move "
                                         "wrong crops to the right folder, then `signlane train signs` on it.")
    signs.add_argument("paths", nargs="+", help="images, videos or folders")
    signs.add_argument("--out", type=Path, required=True, help="output folder")
    signs.add_argument("--model", type=Path, help="classifier ONNX (default: the shipped one, if present)")
    signs.add_argument("--every", type=_positive, default=10, help="every Nth video frame (default 10)")
    signs.add_argument("--size", type=_positive, default=48, help="crop size in pixels (default 48)")
    p.set_defaults(func=_run_autolabel)


def _run_autolabel(args) -> int:
    from signlane.autolabel import autolabel_signs
    from signlane.onnx_model import ModelError
    try:
        report = autolabel_signs(args.paths, args.out, args.model, args.every, args.size)
    except ModelError as e:
        raise UserError(str(e)) from None
    print(json.dumps({"out": str(args.out), "counts": report["counts"], "model": report["model"]}))
    return 1 if report["failed"] else 0


# --- main --------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="signlane",
                                description="Build, train and run the vision stack of a small self-driving car: "
                                            "lane following and traffic signs.")
    p.add_argument("--version", action="version", version=f"signlane {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True, metavar="<command>")
    for add in (_add_infer, _add_eval, _add_gen, _add_train, _add_export, _add_classify, _add_autolabel, _add_demo,
                _add_map):
        add(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except UserError as e:
        print(f"signlane {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
