"""``flexkin calibrate MECH.toml --data MEAS.csv --fit KEY [--fit KEY ...] [--out CALIBRATED.toml]
[--report DIR] [--plot FILE] [--json] [--model kirchhoff|cosserat]``.

Wiring into flexkin's command line (``flexkin/cli.py``), as ``flexkin study``::

    from .calibration.cli import add_calibrate_parser, run_calibrate_command
    add_calibrate_parser(sub)
    handler = {..., "calibrate": run_calibrate_command}[a.command]

Prints the table (or with ``--json`` the SPEC §4 object) on stdout; files written are named on
stderr (``written: FILE``).  Bad input (a bad file, row, key or option) is one line on stderr
and exit status 2.  A fit that leaves parameters unidentified or rows as outliers is an answer
(exit 0; the table and the JSON say so).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from ..core import cli_args

__all__ = ["add_calibrate_parser", "run_calibrate_command"]

EXIT_USAGE = 2
_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


def add_calibrate_parser(sub: Any) -> None:
    """Add the ``calibrate`` sub-command to an argparse sub-parsers object.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        From ``parser.add_subparsers``.
    """
    c = sub.add_parser("calibrate", help="identify a prototype's parameters from measured (inputs, pose) rows")
    c.add_argument("mechanism", help="the nominal mechanism file (TOML, docs/mechanism_file.md)")
    c.add_argument("--data", required=True, metavar="MEAS.csv",
                   help="measurements: CSV with kind,u1,u2,u3,x,y,theta_deg (docs/calibration.md)")
    c.add_argument("--fit", action="append", required=True, metavar="KEY",
                   help="a parameter to fit, e.g. 'leg[*].offset', 'rod.E', 'leg[2].origin', 'platform.attach' "
                        "(repeat the option for more)")
    c.add_argument("--out", metavar="CALIBRATED.toml", help="write the calibrated mechanism file (only the fitted "
                                                            "keys differ from the input)")
    c.add_argument("--report", metavar="DIR", help="write report.md, report.html and the figure into DIR")
    c.add_argument("--plot", metavar="FILE", help="write the figure (measured vs predicted, residuals per row)")
    c.add_argument("--json", action="store_true", help="print the JSON result")
    c.add_argument("--loss", choices=_LOSSES, default="linear", help="robust loss of the least squares "
                                                                     "(default linear)")
    c.add_argument("--f-scale", type=cli_args.positive, default=1.0, metavar="Z",
                   help="soft margin of a robust loss, in standard deviations (default 1)")
    c.add_argument("--absolute-sigma", action="store_true",
                   help="take the file's standard deviations as exact (default: scale the covariance by the "
                        "reduced chi-square)")
    c.add_argument("--model", choices=("kirchhoff", "cosserat"), default="kirchhoff",
                   help="cosserat: refine every prediction with extension, shear and the rods' weight ([rod] density, "
                        "[environment] gravity), so that a sag is not absorbed into wrong geometry (slower)")
    c.add_argument("--no-loo", action="store_true", help="skip the leave-one-out refits")
    c.add_argument("--max-mode", type=cli_args.max_mode, default=2, metavar="Q",
                   help="largest d-mode searched when matching rows (default 2)")


def _fail(msg: str) -> int:
    print(msg, file=sys.stderr)
    return EXIT_USAGE


def _writable_file(path: str, flag: str) -> str | None:
    if os.path.isdir(path):
        return f"flexkin calibrate: {flag} {path!r} is a directory; give a file name"
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        return f"flexkin calibrate: {flag} {path!r}: the directory {parent!r} does not exist"
    if not os.access(parent, os.W_OK):
        return f"flexkin calibrate: {flag} {path!r}: the directory {parent!r} is not writable"
    return None


def run_calibrate_command(a: argparse.Namespace) -> int:
    """Run ``flexkin calibrate`` from parsed arguments; returns the exit status.

    Parameters
    ----------
    a : argparse.Namespace
        From the parser of :func:`add_calibrate_parser`.

    Returns
    -------
    int
        0, or 2 for bad input (one line on stderr).
    """
    from ..errors import MechanismError
    from .fit import calibrate
    from .report import write_calibrated_toml, write_report

    if a.out:
        msg = _writable_file(a.out, "--out")
        if msg:
            return _fail(msg)
        if os.path.abspath(a.out) == os.path.abspath(a.mechanism):
            return _fail(f"flexkin calibrate: --out {a.out!r} is the input mechanism file; give another name")
    if a.plot:
        msg = _writable_file(a.plot, "--plot")
        if msg:
            return _fail(msg)
        if os.path.splitext(a.plot)[1].lower() not in (".png", ".pdf", ".svg"):
            return _fail(f"flexkin calibrate: --plot {a.plot!r}: use a .png, .pdf or .svg file")
    try:
        res = calibrate(a.mechanism, a.data, a.fit, loss=a.loss, f_scale=a.f_scale, absolute_sigma=a.absolute_sigma,
                        max_mode=a.max_mode, loo=not a.no_loo, model=a.model)
    except (MechanismError, ValueError) as e:
        return _fail(str(e) if str(e).startswith("flexkin") else f"flexkin calibrate: {e}")
    if a.json:
        print(json.dumps(res.to_dict(), allow_nan=False))
    else:
        print(res.table())
    try:
        if a.out:
            write_calibrated_toml(res, a.mechanism, a.out)
            print(f"written: {a.out}", file=sys.stderr)
        if a.plot:
            res.plot(a.plot)
            print(f"written: {a.plot}", file=sys.stderr)
        if a.report:
            for p in write_report(res, a.report, mechanism_path=a.mechanism, data_path=a.data, fit=a.fit):
                print(f"written: {p}", file=sys.stderr)
    except OSError as e:
        return _fail(f"flexkin calibrate: cannot write: {e}")
    return 0
