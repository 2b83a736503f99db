"""Progress on stderr when it is a terminal, ``--quiet`` to silence it (issue 18, defect 8)."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import pytest

from flexkin.cli import main

EX = Path(__file__).resolve().parents[1] / "examples"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:  # what tqdm and flexkin see on a real terminal
        return True


def _run(monkeypatch, capsys, args, tty: bool) -> str:
    capsys.readouterr()
    err = _Terminal() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    code = main([str(a) for a in args])
    monkeypatch.undo()
    assert code == 0
    return err.getvalue()


FK = ["fk", EX / "unit_3rfr.toml", "--inputs", "90.46", "-139.47", "-12.03", "--stable-only"]
PATH = ["path", EX / "mixed_legs.toml", "--from", "0", "0", "6", "--to", "0.05", "0", "6", "--steps", "4"]
WS = ["workspace", EX / "unit_3rfr.toml", "--theta", "20", "--step", "0.1", "--bounds", "-0.6", "0.6", "-0.6", "0.6",
      "--first-aspect"]


@pytest.mark.parametrize("args, marker", [(FK, "flexkin fk"), (PATH, "flexkin path"), (WS, "workspace")],
                         ids=["fk", "path", "workspace"])
def test_progress_on_a_terminal_and_quiet_silences_it(monkeypatch, capsys, args, marker):
    shown = _run(monkeypatch, capsys, args, tty=True)
    assert marker in shown and ("elapsed" in shown or "%" in shown or "pt" in shown), shown[:300]
    assert marker not in _run(monkeypatch, capsys, args + ["--quiet"], tty=True)
    assert marker not in _run(monkeypatch, capsys, args, tty=False)  # pipes and files get no bar


@pytest.mark.parametrize("tty, quiet, expected", [(True, False, True), (True, True, False), (False, False, False)])
def test_reproduce_progress_follows_the_terminal(monkeypatch, tmp_path, tty, quiet, expected):
    import flexkin.reproduce as rep

    seen = {}

    def fake(out, quick=False, progress=True):
        seen["progress"] = progress
        return rep.ReproduceResult(Path(out), Path(out) / "report.md", (), [], [], {}, 0.0)

    monkeypatch.setattr(rep, "reproduce", fake)
    monkeypatch.setattr(sys, "stderr", _Terminal() if tty else io.StringIO())
    assert main(["reproduce", "--out", str(tmp_path), "--quick"] + (["--quiet"] if quiet else [])) == 0
    monkeypatch.undo()
    assert seen["progress"] is expected


def test_study_has_quiet():
    from flexkin.cli import _build_parser

    a = _build_parser().parse_args(["study", "x.toml", "--out", "d", "--quiet"])
    assert a.quiet is True


# ---- issue 27, item 9: ik, fk and path show a bar that advances, not a ticker ------------------
IK = ["ik", EX / "unit_3rfr.toml", "--pose", "0.05", "0.02", "20"]


@pytest.mark.parametrize("args", [IK, FK, PATH], ids=["ik", "fk", "path"])
def test_ik_fk_and_path_draw_a_bar_that_advances(monkeypatch, capsys, args):
    """The bar shows the share of the work done (several percentages, up to at least 85 %) and
    the stage, not only the elapsed time."""
    import re

    shown = _run(monkeypatch, capsys, args, tty=True)
    done = sorted({int(p) for p in re.findall(r"(\d+)%\|", shown)})
    assert len(done) >= 3 and done[-1] >= 85, shown[-400:]
    assert re.search(r"flexkin (ik|fk|path)[^:\r]*: [a-zA-Z]", shown), shown[-400:]


def test_solvers_report_progress_in_order_and_print_nothing(capsys, examples_dir):
    """ik, fk and follow_path call ``progress(fraction, stage)`` with fractions that never go
    back, from the start to 1 (the last report), and write nothing themselves."""
    import numpy as np

    import flexkin

    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    capsys.readouterr()
    runs = {}
    for name, call in (("ik", lambda cb: flexkin.ik(mech, (0.05, 0.02, np.radians(20)), progress=cb)),
                       ("fk", lambda cb: flexkin.fk(mech, np.radians([90.46, -139.47, -12.03]), progress=cb)),
                       ("path", lambda cb: flexkin.follow_path(mech, (0.05, 0.02, np.radians(20)),
                                                               (0.1, 0.02, np.radians(20)), steps=5, progress=cb))):
        seen = []
        res = call(lambda f, stage: seen.append((f, stage)))
        runs[name] = seen
        assert len(seen) >= 3, (name, seen)
        fr = [f for f, _ in seen]
        assert all(0.0 <= f <= 1.0 for f in fr) and fr == sorted(fr), (name, seen)
        assert all(isinstance(s, str) and s for _, s in seen)
        assert res is not None
    assert runs["path"][-1][0] >= 0.9 and runs["ik"][-1][0] == 1.0
    out, err = capsys.readouterr()
    assert out == "" and err == ""
