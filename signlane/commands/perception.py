"""`signlane infer` and `eval`: perception on images, videos and seeded test sets."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from signlane.commands.common import UserError, add_config_args, load_config, pixels_arg, positive, size_arg


# --- infer -------------------------------------------------------------------------------------
def add_infer(sub) -> None:
    p = sub.add_parser("infer", help="run the pipeline on images, folders and videos",
                       description="Run lane detection, sign proposals and steering on images, folders of "
                                   "images/videos, and video files. Writes annotated images/videos (and a contact "
                                   "sheet <stem>_sheet.png per video) with --out and one JSON object per frame with "
                                   "--json FILE ('-' for stdout). The camera need not be measured: each input's pitch "
                                   "and height are estimated from its own frames (the vanishing point of the road's "
                                   "lines; a video's first 48 frames) and the summary reports them; the field of view "
                                   "stays camera.hfov_deg. Setting camera.pitch_deg, camera.height_m or "
                                   "camera.roll_deg (or camera.estimate=off) uses the configured camera instead. A video "
                                   "is driven as the car would drive it: the closed-loop stack of `drive` and `run` "
                                   "(junctions, signs placed by odometry, stops and turns in the command's state) on "
                                   "the video's own clock, the car taken to do what it was told; images, and videos "
                                   "with --open-loop, get the lane controller's steering frame by frame. A bad "
                                   "input gets one error line; the rest still runs; the exit code is 1 if any input "
                                   "failed.")
    p.add_argument("paths", nargs="+", help="image files, video files or folders")
    p.add_argument("--out", type=Path, help="folder for annotated images/videos (and masks)")
    p.add_argument("--json", dest="json_path", metavar="FILE", help="write per-frame JSON lines here ('-' = stdout)")
    p.add_argument("--lanes", metavar="METHOD",
                   help="lane method: auto (default: road-edges on a kerbed carriageway such as VIA's, "
                        "sliding-window on painted lanes), road-edges, sliding-window, canny-scan, color-hough, "
                        "vector-spline, segnet (learned; --save-masks then writes its marking mask)")
    p.add_argument("--save-masks", action="store_true", help="write <stem>_lane.png (0/255) beside each annotated image, and <stem>_drivable.png "
                        "(the road surface, 0/255) where the method has a road output (segnet with a road model, "
                        "road-edges, auto on a kerbed road)")
    p.add_argument("--open-loop", action="store_true",
                   help="videos frame by frame through the open-loop lane controller, as images are (no "
                        "odometry, junctions, stops or turns)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bars")
    p.add_argument("--max-pixels", type=pixels_arg, default=4096 * 4096, metavar="WxH",
                   help="refuse images and video frames with more pixels than this, read from the file's header "
                        "before decoding (default 4096x4096)")
    add_config_args(p)
    p.set_defaults(func=_run_infer)


def _run_infer(args) -> int:
    from signlane.infer import run_infer
    from signlane.onnx_model import ModelError
    cfg = load_config(args)
    try:
        summary = run_infer(args.paths, cfg, out=args.out, json_path=args.json_path, save_masks=args.save_masks,
                            progress=args.progress, max_pixels=args.max_pixels, open_loop=args.open_loop)
    except (ValueError, ModelError) as e:
        raise UserError(str(e)) from None
    print(summary.table(), file=sys.stderr)
    return 1 if summary.failed else 0


# --- eval --------------------------------------------------------------------------------------
def add_eval(sub) -> None:
    p = sub.add_parser("eval", help="score lane methods or sign proposals on a seeded synthetic test set",
                       description="Render a seeded synthetic test set and print a score table.")
    kinds = p.add_subparsers(dest="kind", required=True, metavar="{lanes,proposals,signs,masks,pilot}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--n", type=positive, default=500, help="frames (default 500)")
    common.add_argument("--seed", type=int, default=1000, help="test-set seed (default 1000)")
    common.add_argument("--hard", action="store_true", help="the hard set: glare, blur, noise, worn paint, shadows")
    common.add_argument("--variant", choices=["robust", "published", "both"], default="robust",
                        help="robust (default), the source's published baseline, or both")
    common.add_argument("--csv", type=Path, help="also write the table as CSV")
    common.add_argument("--plot", type=Path, help="also write a PNG plot")
    lanes = kinds.add_parser("lanes", parents=[common], help="lane found %%, offset/heading errors, curvature sign",
                             description="Lane found %, median and 95th percentile lateral-offset error (fraction "
                                         "of lane width), the median error over the frames every listed method "
                                         "found (a method that finds more frames finds harder ones), heading "
                                         "error, curvature sign agreement, ms/frame.")
    lanes.add_argument("--method", action="append", help="lane method (repeatable; default: all available)")
    lanes.add_argument("--size", type=size_arg, default=(320, 240), help="frame size WxH (default 320x240)")
    lanes.add_argument("--lanes-model", type=Path, help="segnet's ONNX model (default: the shipped one)")
    masks = kinds.add_parser("masks", help="lane-marking F1 of the segmentation model on a lane dataset",
                             description="Precision, recall and F1 of segnet's lane-marking mask against a lane "
                                         "dataset's masks (make a fresh one with `signlane gen lanes --seed S`), "
                                         "with a pixel tolerance, at each frame's size, and the exact pixel IoU; "
                                         "pixels a mask marks 255 (no label) count nowhere. The mask scored is the "
                                         "one `infer --lanes segnet --save-masks` writes: on frames 3 or more times "
                                         "the model's size, its band sharpened to the frame's own paint.")
    masks.add_argument("data", type=Path, help="lane dataset folder (labels.jsonl, images/, masks/)")
    masks.add_argument("--model", type=Path, help="ONNX model (default: the shipped signlane/models/lanes.onnx)")
    masks.add_argument("--tol", type=int, default=2, help="tolerance in pixels (default 2)")
    prop = kinds.add_parser("proposals", parents=[common], help="recall of signs >= 20 px and false proposals/frame",
                            description="Recall of ground-truth signs (box IoU >= 0.5, signs >= --min-size px) and "
                                        "false proposals per frame.")
    prop.add_argument("--min-size", type=int, default=20, help="smallest sign side counted, px (default 20)")
    prop.add_argument("--size", type=size_arg, default=(640, 480), help="frame size WxH (default 640x480)")
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
    signs.add_argument("--out", type=Path, help="write confusion.png and errors_<class>.png/.txt (each wrong crop "
                                                 "captioned with its file, what it was taken for and the score) here")
    pilot = kinds.add_parser("pilot", help="pilot steering against the teacher on recorded drives",
                             description="Steering error (MAE, RMSE) of one or more pilots against the teacher's "
                                         "own steering on drive recordings (`signlane gen pilot` or `sim --record` "
                                         "folders; record fresh ones on seeds not trained on): overall, by the "
                                         "teacher's lane curvature (straight, bend, turn) and by desire; several "
                                         "--model side by side. With --out: steering.png (predicted vs teacher "
                                         "over time) and disagree_<model>.png (the frames they differ most on).")
    pilot.add_argument("data", nargs="+", type=Path, help="recording folders")
    pilot.add_argument("--model", type=Path, action="append", required=True,
                       help="pilot ONNX file (repeat to compare)")
    pilot.add_argument("--out", type=Path, help="folder for steering.png and disagree_<model>.png")
    pilot.add_argument("--json", dest="json_path", type=Path, help="also write the scores as JSON")
    p.set_defaults(func=_run_eval)


def _run_eval(args) -> int:
    if args.kind == "pilot":
        from signlane.eval_pilot import eval_pilot, format_table
        from signlane.onnx_model import ModelError
        try:
            result = eval_pilot(args.data, args.model, args.out)
        except (ModelError, ValueError, OSError) as e:
            raise UserError(str(e)) from None
        print(f"{result['frames']} frames of {result['drives']} drive(s)")
        print(format_table(result))
        if args.json_path:
            from signlane.fileio import atomic_write_json
            atomic_write_json(args.json_path, result)
        return 0
    if args.kind in ("signs", "masks"):
        from signlane.onnx_model import ModelError
        try:
            if args.kind == "signs":
                from signlane.evaluate import eval_signs
                result = eval_signs(args.data, args.model, args.min_score, args.out)
            else:
                from signlane.eval_masks import eval_masks
                result = eval_masks(args.data, args.model, args.tol)
        except (ModelError, ValueError, OSError) as e:
            raise UserError(str(e)) from None
        print(json.dumps(result, indent=1))
        return 0
    variants = ["robust", "published"] if args.variant == "both" else [args.variant]
    if args.kind == "lanes":
        from signlane import lanes
        from signlane.evaluate import add_common_errors, eval_lanes, format_table, plot_lanes, write_csv
        from signlane.onnx_model import ModelError
        methods = args.method or lanes.available()
        model = {"model": str(args.lanes_model)} if args.lanes_model else {}
        runs = [(m, v) for m in methods for v in variants
                if not (m == "segnet" and v == "published")]  # a learned method has no published baseline
        errors = [{} for _ in runs]
        try:
            rows = [eval_lanes(m, args.n, args.seed, args.hard, v, *args.size,
                               overrides=model if m == "segnet" else None, errors=e) for (m, v), e in zip(runs, errors)]
        except (ValueError, ModelError) as e:
            raise UserError(str(e)) from None
        add_common_errors(rows, errors)
        print(format_table(rows))
        print(f"off med shared: the median offset error over the {rows[0]['common_frames'] if rows else 0} frames "
              "that every method above found")
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
