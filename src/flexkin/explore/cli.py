"""``flexkin explore MECH.toml [--port P] [--no-browser] [--pose X Y THETA] [--load FX FY MZ] [--max-mode Q]``.

Wiring into flexkin's command line (``flexkin/cli.py``)::

    from .explore.cli import add_explore_parser, run_explore_command
    add_explore_parser(sub)                    # sub = parser.add_subparsers(...)
    handler = {..., "explore": run_explore_command}[a.command]

:func:`run_explore_command` loads the mechanism first: a bad file prints the library's one-line
message (``str(MechanismError)``, naming the file and the key) on stderr and returns 2 before any
server starts; so do a bad start pose, load or port.  Otherwise it serves the explorer until
Ctrl-C or until the last browser tab closes, and returns 0.  Until the command is wired, the
same runs as ``python -m flexkin.explore MECH.toml ...``.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any, Sequence

from ..core import cli_args

__all__ = ["add_explore_parser", "run_explore_command", "main"]

EXIT_USAGE = 2


def add_explore_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``explore`` sub-command to ``subparsers`` (from ``parser.add_subparsers()``)."""
    p = subparsers.add_parser(
        "explore", help="interactive explorer in the browser: all equilibria drawn live",
        description="Start the interactive explorer (docs/explore.md) on localhost and open it in the browser: "
                    "drag the platform (IK) or move the inputs (FK); all equilibria are drawn and listed, the "
                    "selected one is tracked continuously with its events (d-mode change, stability, "
                    "singularities, feasibility). Stops on Ctrl-C or when the last tab is closed.")
    p.add_argument("mechanism", metavar="MECH.toml", help="mechanism file (TOML)")
    p.add_argument("--port", type=cli_args.integer_in(0, 65535), default=None, metavar="P",
                   help="port on localhost (default 5006, or a free port if 5006 is taken; 0: any free port)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser; just print the address")
    p.add_argument("--pose", nargs=3, type=cli_args.finite, metavar=("X", "Y", "THETA"),
                   help="start pose [m m deg] (default: the centroid of the legs' origins, 0 deg)")
    p.add_argument("--load", nargs=3, type=cli_args.finite, metavar=("FX", "FY", "MZ"),
                   help="load wrench on the platform at P [N N N*m] (default: the file's)")
    p.add_argument("--max-mode", type=cli_args.max_mode, default=2, help="largest d-mode of any rod (default 2)")
    return p


def run_explore_command(args: argparse.Namespace) -> int:
    """Run ``flexkin explore`` for parsed ``args``; return the exit status."""
    from flexkin.errors import MechanismError
    from flexkin.mechanism import load_mechanism

    try:
        mech = load_mechanism(args.mechanism)
    except MechanismError as e:
        print(str(e), file=sys.stderr)
        return EXIT_USAGE
    pose = None
    if args.pose is not None:
        pose = (args.pose[0], args.pose[1], math.radians(args.pose[2]))
    try:  # the web library is an optional part of the install
        from .server import serve
    except ImportError as e:
        print(f"flexkin explore: the explorer needs the 'bokeh' package ({e})", file=sys.stderr)
        return EXIT_USAGE
    return serve(mech, port=args.port, open_browser=not args.no_browser, pose=pose, load=args.load,
                 max_mode=args.max_mode)


def main(argv: Sequence[str] | None = None) -> int:
    """``flexkin explore ...`` on its own (until the command is wired into ``flexkin``):
    ``python -m flexkin.explore MECH.toml ...``."""
    import matplotlib

    matplotlib.use("Agg")
    parser = argparse.ArgumentParser(prog="flexkin")
    sub = parser.add_subparsers(dest="command", required=True)
    add_explore_parser(sub)
    try:
        args = parser.parse_args(["explore", *(sys.argv[1:] if argv is None else argv)])
    except SystemExit as e:  # argparse: usage and one message on stderr
        return int(e.code) if isinstance(e.code, int) else EXIT_USAGE
    return run_explore_command(args)
