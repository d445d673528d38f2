"""`signlane <subcommand>`: thin argument parsing; each subcommand calls one library function.

Heavy imports stay inside the subcommand that needs them, so `signlane --help` is instant.
"""
from __future__ import annotations

import argparse
import logging
import sys

from signlane import __version__
from signlane.commands.common import UserError
from signlane.commands.drive import add_drive, add_export_drive
from signlane.commands.models import add_autolabel, add_classify, add_export, add_quantize, add_ship, add_train
from signlane.commands.perception import add_eval, add_infer
from signlane.commands.run import add_run
from signlane.commands.settings import add_config
from signlane.commands.sim import add_sim
from signlane.commands.world import add_demo, add_gen, add_map

log = logging.getLogger("signlane")


# --- main --------------------------------------------------------------------------------------
def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """argv: the command line to be parsed; a `train` one gets a flag per Lightning Trainer
    argument (reading them imports Lightning, which no other command needs)."""
    p = argparse.ArgumentParser(prog="signlane",
                                description="Build, train and run the vision stack of a small self-driving car: "
                                            "lane following and traffic signs.")
    p.add_argument("--version", action="version", version=f"signlane {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True, metavar="<command>")
    words = [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("-")]
    lightning_flags = bool(words) and words[0] == "train"
    for add in (add_infer, add_eval, add_gen, lambda s: add_train(s, lightning_flags), add_export, add_quantize,
                add_ship, add_classify, add_autolabel, add_demo, add_map, add_drive, add_export_drive, add_sim, add_run,
                add_config):
        add(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser(argv).parse_args(argv)
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
