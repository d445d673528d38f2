"""`signlane config`: the resolved config (defaults, a TOML file, --set overrides) as TOML."""
from __future__ import annotations

from signlane.commands.common import add_config_args, load_config


def add_config(sub) -> None:
    p = sub.add_parser("config", help="print the resolved config as TOML (a starting point for --config)",
                       description="Print the config every command starts from, as a TOML file that --config "
                                   "reads: the defaults, then the --config file's tables, then each --set. Save it, "
                                   "edit what you need, pass it back with --config.")
    p.add_argument("--print", action="store_true", help="print it (the default action; accepted for clarity)")
    add_config_args(p, "TOML config file to start from instead of the defaults")
    p.set_defaults(func=_run_config)


def _run_config(args) -> int:
    print(load_config(args).to_toml(), end="")
    return 0
