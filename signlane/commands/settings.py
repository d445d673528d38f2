"""`signlane config`: the resolved config (defaults, a TOML file, --set overrides) as TOML."""
from __future__ import annotations

from pathlib import Path

from signlane.commands.common import UserError


def add_config(sub) -> None:
    p = sub.add_parser("config", help="print the resolved config as TOML (a starting point for --config)",
                       description="Print the config every command starts from, as a TOML file that --config "
                                   "reads: the defaults, then the --config file's tables, then each --set. Save it, "
                                   "edit what you need, pass it back with --config.")
    p.add_argument("--print", action="store_true", help="print it (the default action; accepted for clarity)")
    p.add_argument("--config", type=Path, help="TOML config file to start from instead of the defaults")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one setting, e.g. --set camera.pitch_deg=12 (repeatable)")
    p.set_defaults(func=_run_config)


def _run_config(args) -> int:
    from signlane.config import Config
    try:
        cfg = Config.load(args.config, args.overrides)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(cfg.to_toml(), end="")
    return 0
