"""Subcommand modules of `signlane`; each has `_add_<name>(subparsers)` and a runner."""
