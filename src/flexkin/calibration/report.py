"""Files of a calibration: the calibrated mechanism file and the ``--report`` page."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Sequence

from .text import fmt_value, rms_text

__all__ = ["write_calibrated_toml", "calibrated_text", "write_report", "markdown"]


def calibrated_text(res, mechanism_path: str | Path) -> str:
    """The calibrated mechanism file's text: the input file with only the fitted keys changed.

    Parameters
    ----------
    res : CalibrationResult
    mechanism_path : str or Path
        The starting mechanism file.

    Returns
    -------
    str
    """
    from .params import parse_fit_keys
    from .toml_edit import calibrated_toml

    text = Path(mechanism_path).read_text(encoding="utf-8-sig")
    raw = tomllib.loads(text)
    keys = list(dict.fromkeys(p.fit_key for p in res.parameters))
    params = parse_fit_keys(keys, res.mechanism, raw)
    by = {p.key: p.value for p in res.parameters}
    values = [by[p.name] for p in params]
    note = (f"calibrated by flexkin calibrate from {res.source} (fitted: {', '.join(keys)}; "
            f"RMS after: {rms_text(res.rms_after, named=False)})")
    return calibrated_toml(text, raw, params, values, note)


def write_calibrated_toml(res, mechanism_path: str | Path, out: str | Path) -> Path:
    """Write :func:`calibrated_text` to ``out``.

    Parameters
    ----------
    res : CalibrationResult
    mechanism_path : str or Path
    out : str or Path

    Returns
    -------
    Path
    """
    out = Path(out)
    out.write_text(calibrated_text(res, mechanism_path), encoding="utf-8")
    return out


def _row_err(r, which: str) -> str:
    v = {"before": r.residual_before, "after": r.residual_after, "loo": r.loo}[which]
    if v is None or (which == "after" and r.outlier):
        return "–"
    if r.kind == "fk":
        return f"{math.hypot(v[0], v[1]) * 1e3:.2f} mm, {abs(v[2]):.2f}°"
    return ", ".join(f"{x * 1e3:+.2f} mm" if u == "m" else f"{x:+.2f}°" for x, u in zip(v, r.units))


def markdown(res, figure: str | None = None, command: str = "") -> str:
    """The calibration as a Markdown section (used by ``--report`` and ``flexkin reproduce``).

    Parameters
    ----------
    res : CalibrationResult
    figure : str, optional
        Relative path of the figure to show.
    command : str
        The command line to show.

    Returns
    -------
    str
    """
    md = []
    if command:
        md += ["```", command, "```", ""]
    md += ["| parameter | initial | estimate | std. error | 95 % interval |", "|---|---|---|---|---|"]
    for p in res.parameters:
        ci = "–" if p.ci95 is None else f"[{fmt_value(p.ci95[0], p.unit)}, {fmt_value(p.ci95[1], p.unit)}]"
        md.append(f"| `{p.key}` | {fmt_value(p.initial, p.unit)} | {fmt_value(p.value, p.unit)} | "
                  f"{fmt_value(p.stderr, p.unit) if p.stderr is not None else 'not identified'} | {ci} |")
    sig = "from the sigmas as given" if res.absolute_sigma else "scaled by the residual scale " + (
        f"{res.scale:.3g}" if math.isfinite(res.scale) else "(none: no degrees of freedom)")
    md += ["", f"χ² = {res.chi2:.4g} on {res.dof} degrees of freedom; standard errors {sig}.", ""]
    sv = ", ".join(f"{v:.3g}" for v in res.singular_values)
    md.append(f"**Identifiability.** Singular values of the parameter Jacobian scaled by typical changes "
              f"(relative to the largest): {sv}.")
    if not res.combinations:
        md.append("Every fitted parameter is identified by these data.")
    for c in res.combinations:
        md.append(f"{'Weakly identified' if c.identifiable else 'Not identifiable'} (singular value "
                  f"{c.singular_value:.2g}): `{c.text}`.")
    md += ["", "| row | kind | label | solution | before | after | leave-one-out |", "|---|---|---|---|---|---|---|"]
    for r in res.rows:
        lab = r.label + (f" — **outlier**: {r.reason}" if r.outlier else "") + (f" ({r.note})" if r.note else "")
        md.append(f"| {r.index} | {r.kind} | {lab} | {r.solution if r.solution is not None else '–'} "
                  f"({r.modes or '–'}) | {_row_err(r, 'before')} | {_row_err(r, 'after')} | {_row_err(r, 'loo')} |")
    md += ["", f"RMS over the fitted rows: before {rms_text(res.rms_before, named=False)}; after {rms_text(res.rms_after, named=False)}; "
               f"leave-one-out {rms_text(res.loo_rms, named=False)}.", ""]
    if res.message:
        md += [f"Note: {res.message}.", ""]
    if figure:
        md += [f"![calibration]({figure})", "",
               "*Left: FK rows, measured (black) and predicted platform poses before (grey) and after (blue) "
               "the fit. Middle: IK rows, predicted minus measured inputs. Right: each row's RMS residual in "
               "standard deviations, before and after, and its leave-one-out prediction error (red circles).*", ""]
    return "\n".join(md)


def write_report(res, out: str | Path, mechanism_path: str | Path | None = None, data_path: str | None = None,
                 fit: Sequence[str] = ()) -> list[Path]:
    """Write ``report.md``, ``report.html``, ``calibration.png``, ``calibration.json`` and (with
    the mechanism file) ``calibrated.toml`` into ``out``.

    Parameters
    ----------
    res : CalibrationResult
    out : str or Path
        Directory (created).
    mechanism_path : str or Path, optional
        The starting mechanism file.
    data_path : str, optional
        The measurement file (for the command line shown).
    fit : sequence of str
        The ``--fit`` keys (for the command line shown).

    Returns
    -------
    list of Path
        The files written.
    """
    from ..io.html_report import markdown_to_html  # one Markdown renderer for every report

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    fig = out / "calibration.png"
    res.plot(str(fig))
    written.append(fig)
    js = out / "calibration.json"
    js.write_text(json.dumps(res.to_dict(), allow_nan=False, indent=1), encoding="utf-8")
    written.append(js)
    if mechanism_path is not None:
        toml = out / "calibrated.toml"
        write_calibrated_toml(res, mechanism_path, toml)
        written.append(toml)
    cmd = ""
    if mechanism_path is not None and data_path is not None:
        cmd = f"flexkin calibrate {mechanism_path} --data {data_path} " + " ".join(f"--fit '{k}'" for k in fit)
    name = getattr(res.mechanism, "name", "")
    md = [f"# Calibration of {name}", "", f"Data: `{res.source}`, {len(res.rows)} rows; loss {res.loss}; "
          f"{res.elapsed:.1f} s.", "", markdown(res, fig.name, cmd)]
    if mechanism_path is not None:
        md += ["The calibrated mechanism file is [calibrated.toml](calibrated.toml) (only the fitted keys differ "
               "from the input); the JSON is [calibration.json](calibration.json).", ""]
    text = "\n".join(md)
    (out / "report.md").write_text(text, encoding="utf-8")
    written.append(out / "report.md")
    (out / "report.html").write_text(markdown_to_html(text, out, f"calibration of {name}"), encoding="utf-8")
    written.append(out / "report.html")
    return written
