"""Design studies: study files, grid keys, single-process runs, resumption, scaling, CLI errors.

The Dask runs (local cluster, ``dask scheduler`` subprocesses, killed workers) are in
``test_study_dask.py``.
"""

from __future__ import annotations

import json
import math
import shutil
import time
import tomllib

import numpy as np
import pytest

from flexkin.mechanism import mechanism_from_dict
from flexkin.study import METRICS, StudyError, load_study, read_table, run_study
from flexkin.study.cli import main as study_main
from flexkin.study.evaluate import INDEX_SUMMARIES
from flexkin.study.grid import apply_design, parse_key
from test_study_support import EXAMPLES, TINY, free_port, reference_rows, strip, write_study

MINIMAL = '''
mechanism = "unit_3rfr.toml"            # relative to the study file
orientations = [0, 20]                  # deg
[grid]
"rod.length" = [0.9, 1.0, 1.1]          # explicit values
"rod.EI" = {start = 0.5, stop = 2.0, num = 4}
'''


def _base(name: str) -> tuple[dict, object]:
    path = EXAMPLES / name
    data = tomllib.loads(path.read_text())
    return data, mechanism_from_dict(data, source=str(path))


# ---- study files ---------------------------------------------------------------------
def test_minimal_form_as_written(tmp_path):
    shutil.copy(EXAMPLES / "unit_3rfr.toml", tmp_path / "unit_3rfr.toml")
    spec = load_study(write_study(tmp_path, MINIMAL))
    assert spec.mechanism_path == str(tmp_path / "unit_3rfr.toml")
    assert spec.keys == ("rod.length", "rod.EI")
    assert spec.grid[1].values == (0.5, 1.0, 1.5, 2.0)
    assert spec.orientations == (0.0, 20.0)
    assert spec.metrics == tuple(METRICS)  # default: every metric
    assert spec.n_designs == 12 and spec.n_tasks == 24
    tasks = spec.tasks()
    # row order: design (first key slowest), then orientation
    assert [(t.design, dict(t.params)["rod.length"], dict(t.params)["rod.EI"], t.theta_deg) for t in tasks[:5]] == [
        (0, 0.9, 0.5, 0.0), (0, 0.9, 0.5, 20.0), (1, 0.9, 1.0, 0.0), (1, 0.9, 1.0, 20.0), (2, 0.9, 1.5, 0.0)]
    assert len({t.key for t in tasks}) == 24
    assert spec.tasks()[7].key == tasks[7].key  # keys are content hashes: the same in every run
    mech = mechanism_from_dict(dict(tasks[7].mechanism), source="<t>")
    assert [leg.rod.length for leg in mech.legs] == [0.9] * 3
    assert [leg.rod.EI for leg in mech.legs] == [2.0] * 3


def _cli_error(tmp_path, capsys, body: str | None, *extra: str, path: str | None = None) -> str:
    study = path or str(write_study(tmp_path, body))
    rc = study_main(["study", study, "--out", str(tmp_path / "out"), "--scheduler", "synchronous", "--quiet", *extra])
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1, err
    assert not (tmp_path / "out" / "results.parquet").exists()
    return err


M = f'mechanism = "{(EXAMPLES / "unit_3rfr.toml").as_posix()}"\norientations = [20]\n'
MIXED = f'mechanism = "{(EXAMPLES / "mixed_legs.toml").as_posix()}"\norientations = [6]\n'


BAD_FILES = [
    (M + '[grid]\n"rod.lenght" = [1.0]\n', "did you mean 'rod.length'"),
    (M + '[grid]\n"leg.orign_radius" = [1.0]\n', "did you mean 'leg.origin_radius'"),
    (M + 'orientation = [1]\n[grid]\n"rod.length" = [1.0]\n', "did you mean 'orientations'"),
    (M + '[grid]\n', "grid: empty"),
    (M, "grid: missing"),
    (M + '[grid]\n"rod.length" = []\n', "empty list"),
    (M + '[grid]\n"rod.length" = {start = 0.9, stop = 1.1, num = 0}\n', "num: must be >= 1"),
    (M + '[grid]\n"rod.length" = {start = 0.9, stop = 1.1, num = 2.5}\n', "num: expected an integer"),
    (M + '[grid]\n"rod.length" = {start = 0.9, num = 3}\n', "stop: missing"),
    (M + '[grid]\n"rod.length" = {start = 0.9, stop = 0.9, num = 3}\n', "equal values"),
    (M + '[grid]\n"rod.length" = {start = 0.9, stop = 1.1, step = 0.1}\n', "unknown key"),
    (M + '[grid]\n"rod.length" = [1.0, -1.0]\n', "must be > 0"),
    (M + '[grid]\n"rod.length" = [1.0, 1.0]\n', "duplicate value 1"),
    (M + '[grid]\n"rod.length" = ["long"]\n', "expected a number"),
    (M + '[grid]\nrod.length = [1.0]\n', "write the key in quotes"),
    (M + '[grid]\n"leg[1].angle" = [10.0]\n', "revolute"),
    (M + '[grid]\n"leg[4].origin_x" = [0.1]\n', "no leg 4"),
    (M + '[grid]\n"leg.origin_x" = [0.1]\n', "per leg"),
    (M + '[grid]\n"rod.length" = [1.0]\n"leg.length" = [1.2]\n', "has no effect"),
    (MIXED + '[grid]\n"rod.EI" = [0.1]\n"rod.E" = [7e10]\n', "conflicts"),
    (M + 'metrics = ["workspace_aera"]\n[grid]\n"rod.length" = [1.0]\n', "did you mean 'workspace_area'"),
    (M + '[grid]\n"rod.length" = [1.0]\n[workspace]\nstep = -0.1\n', "workspace.step: must be > 0"),
    (M + '[grid]\n"rod.length" = [1.0]\n[workspace]\nstpe = 0.1\n', "did you mean 'step'"),
    ('orientations = [20]\n[grid]\n"rod.length" = [1.0]\n', "mechanism: missing"),
    ('mechanism = "no_such_file.toml"\norientations = [20]\n[grid]\n"rod.length" = [1.0]\n', "file not found"),
    (M.replace("orientations = [20]\n", "") + '[grid]\n"rod.length" = [1.0]\n', "orientations: missing"),
    ('mechanism = "x.toml"\norientations = [20\n', "malformed TOML"),
]


@pytest.mark.parametrize("body, expected", BAD_FILES, ids=[e.replace(" ", "_") for _, e in BAD_FILES])
def test_bad_study_file_one_line_exit_2(tmp_path, capsys, body, expected):
    err = _cli_error(tmp_path, capsys, body)
    assert expected in err, err
    assert err.startswith("flexkin study: ") and "study.toml" in err


def test_bad_base_mechanism_and_missing_study(tmp_path, capsys):
    (tmp_path / "bad.toml").write_text("[rod]\nlength = -1\n")
    err = _cli_error(tmp_path, capsys, 'mechanism = "bad.toml"\norientations = [0]\n[grid]\n"rod.length" = [1.0]\n')
    assert "invalid base mechanism" in err and "bad.toml" in err
    err = _cli_error(tmp_path, capsys, None, path=str(tmp_path / "nope.toml"))
    assert "nope.toml: file not found" in err


def test_bad_arguments_exit_2(tmp_path, capsys):
    study = str(write_study(tmp_path, TINY))
    assert study_main(["study", study, "--out", str(tmp_path / "o"), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err
    assert study_main(["study", study, "--out", str(tmp_path / "o"), "--workers", "2", "--scheduler", "x"]) == 2
    assert "not allowed with" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    rc = study_main(["study", study, "--out", str(tmp_path / "file"), "--scheduler", "synchronous"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "not a directory" in err and len(err.splitlines()) == 1


def test_unreachable_scheduler_clear_error_within_timeout(tmp_path, capsys):
    addr = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    t0 = time.perf_counter()
    with pytest.raises(StudyError, match="cannot connect to the Dask scheduler"):
        run_study(write_study(tmp_path, TINY), tmp_path / "out", scheduler=addr, timeout=2, progress=False)
    assert time.perf_counter() - t0 < 15
    rc = study_main(["study", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out"), "--scheduler", addr,
                     "--timeout", "2"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and addr in err and "within 2 s" in err and len(err.splitlines()) == 1
    assert time.perf_counter() - t0 < 30
    with pytest.raises(StudyError, match="bad Dask scheduler address 'localhost'"):
        run_study(tmp_path / "study.toml", tmp_path / "out", scheduler="localhost", timeout=2, progress=False)


# ---- grid keys -----------------------------------------------------------------------
def test_grid_keys_change_what_they_say():
    data, mech = _base("unit_3rfr.toml")

    def build(params):
        return mechanism_from_dict(apply_design(data, mech, params), source="<t>")

    m = build({"rod.length": 1.3, "rod.EI": 0.7})
    assert [leg.rod.length for leg in m.legs] == [1.3] * 3 and [leg.rod.EI for leg in m.legs] == [0.7] * 3
    m = build({"leg.origin_radius": 1.5})
    for a, b in zip(m.legs, mech.legs):
        assert math.hypot(*a.origin) == pytest.approx(1.5)
        assert math.atan2(a.origin[1], a.origin[0]) == pytest.approx(math.atan2(b.origin[1], b.origin[0]))
    m = build({"leg[2].origin_radius": 0.8, "leg[2].origin_angle": -45.0})
    assert m.legs[1].origin == pytest.approx((0.8 / math.sqrt(2), -0.8 / math.sqrt(2)))
    assert m.legs[0].origin == mech.legs[0].origin and m.legs[2].origin == mech.legs[2].origin
    m = build({"platform.scale": 2.0})
    assert m.platform.b == pytest.approx(2.0 * mech.platform.b)
    m = build({"platform.radius": 0.1})
    assert [math.hypot(*b) for b in m.platform.attach] == pytest.approx([0.1] * 3)
    m = build({"load.force_y": -0.5, "load.moment": 0.01})
    assert m.load == (0.0, -0.5, 0.01)
    m = build({"scale": 3.0})
    assert m.platform.b == pytest.approx(3.0 * mech.platform.b)
    np.testing.assert_allclose([leg.origin for leg in m.legs], 3.0 * np.array([leg.origin for leg in mech.legs]),
                               rtol=1e-12)
    assert [leg.rod.length for leg in m.legs] == [3.0] * 3 and [leg.rod.EI for leg in m.legs] == [1.0] * 3
    # the original dict is untouched
    assert data == tomllib.loads((EXAMPLES / "unit_3rfr.toml").read_text())


def test_grid_rod_keys_respect_leg_overrides_and_stiffness():
    data, mech = _base("mixed_legs.toml")  # [rod] L 0.9, E 68e9, r 1.5e-3; leg 2 overrides L 0.85, r 1.8e-3

    def build(params):
        return mechanism_from_dict(apply_design(data, mech, params), source="<t>")

    m = build({"rod.length": 1.0})
    assert m.legs[0].rod.length == 1.0 and m.legs[1].rod.length == 0.85  # leg 2 keeps its own
    assert m.legs[2].rod.length is None  # length-actuated
    m = build({"rod.radius": 1e-3})  # E known: EI = E pi r^4 / 4
    assert m.legs[0].rod.EI == pytest.approx(68e9 * math.pi * 1e-3**4 / 4, rel=1e-12)
    assert m.legs[1].rod.radius == 1.8e-3
    m = build({"leg.radius": 1e-3})
    assert m.legs[1].rod.radius == 1e-3
    m = build({"rod.EI": 0.05})
    assert [leg.rod.EI for leg in m.legs] == [0.05] * 3 and m.legs[0].rod.radius == 1.5e-3
    m = build({"rod.E": 50e9, "leg[2].EI": 0.3})
    assert m.legs[0].rod.EI == pytest.approx(50e9 * math.pi * 1.5e-3**4 / 4, rel=1e-12)
    assert m.legs[1].rod.EI == 0.3
    m = build({"leg[1].angle": 12.0, "scale": 2.0})
    assert math.degrees(m.legs[0].angle) == pytest.approx(12.0)
    assert m.legs[0].range == pytest.approx((-0.2, 0.6))  # a prismatic stroke is a length
    assert m.legs[1].range == mech.legs[1].range  # a revolute range is not


def test_parse_key_suggestions():
    assert parse_key("leg[3].origin_y").leg == 2
    with pytest.raises(ValueError, match="did you mean 'platform.scale'"):
        parse_key("platform.scal")


# ---- runs (single process) -----------------------------------------------------------
def test_synchronous_run_resume_and_table(tmp_path):
    ref = reference_rows()
    study = write_study(tmp_path, TINY)
    out = tmp_path / "out"
    res = run_study(study, out, scheduler="synchronous", progress=False)
    assert (res.n_computed, res.n_reused, res.n_failed, res.n_incomplete) == (4, 0, 0, 0)
    assert strip(res.rows) == ref
    names = [c for c, _ in res.columns]
    assert names[:3] == ["design", "rod.length", "theta_deg"]
    assert names[-4:] == ["complete", "error", "note", "elapsed_s"]
    assert set(METRICS) <= set(names)
    assert [(r["rod.length"], r["theta_deg"]) for r in res.rows] == [(1.0, 10.0), (1.0, 20.0), (1.1, 10.0), (1.1, 20.0)]
    for r in res.rows:
        assert r["complete"] and r["error"] == "" and r["elapsed_s"] > 0
        assert r["workspace_area"] > 0 and r["n_aspects"] == 1
        assert r["workspace_area"] == pytest.approx(r["singularity_free_area"])
        assert r["min_stability_margin"] > 0 and r["max_curvature"] > 0
        assert r["max_strain"] is None  # the unit mechanism has no rod radius
        for name in INDEX_SUMMARIES:  # every index summarised over the largest aspect
            assert r[f"min_{name}"] <= r[f"mean_{name}"] <= r[f"max_{name}"], name
        # the aspect is stable: the platform is stiff in every direction with the actuators locked
        assert r["min_force_stiffness"] > 0 and r["min_moment_stiffness"] > 0 and r["min_cond"] >= 1
        assert r["min_singularity_distance"] >= 0.05 - 1e-12  # half a step: boundary cells
        assert [float(a) for a in r["aspect_areas"].split(";")] == pytest.approx([r["singularity_free_area"]])
    # a longer rod reaches further
    assert res.rows[2]["workspace_area"] > res.rows[0]["workspace_area"]
    # the files
    assert strip(read_table(out)) == ref
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 5 and csv_lines[0].split(",")[:3] == ['"design"', '"rod.length"', '"theta_deg"']
    assert len(list((out / "rows").glob("*.json"))) == 4
    assert json.loads((out / "study.json").read_text())["grid"] == {"rod.length": [1.0, 1.1]}
    figs = {p.name for p in res.figures}
    assert "fig_workspace_area.png" in figs and "fig_max_strain.png" not in figs  # no value: no figure
    assert all(p.stat().st_size > 5000 for p in res.figures)
    # resume: nothing to compute; then one row lost -> only it is computed
    again = run_study(study, out, scheduler="synchronous", progress=False, figures=False)
    assert (again.n_computed, again.n_reused) == (0, 4) and again.rows == res.rows
    victim = sorted((out / "rows").glob("*.json"))[0]
    victim.unlink()
    third = run_study(study, out, scheduler="synchronous", progress=False, figures=False)
    assert (third.n_computed, third.n_reused) == (1, 3) and strip(third.rows) == ref
    # a grid that grows reuses the rows it shares
    grown = write_study(tmp_path, TINY.replace("[1.0, 1.1]", "[1.0, 1.05, 1.1]"), "grown.toml")
    res4 = run_study(grown, out, scheduler="synchronous", progress=False, figures=False)
    assert (res4.n_computed, res4.n_reused) == (2, 4)
    assert [r["design"] for r in res4.rows] == [0, 0, 1, 1, 2, 2]
    assert strip([res4.rows[i] for i in (0, 1, 4, 5)]) == [dict(r, design=2 * (r["design"])) for r in ref]


def test_failing_design_is_a_row_with_its_error(tmp_path, capsys):
    body = TINY.replace('"rod.length" = [1.0, 1.1]', '"leg[1].origin_x" = [-0.8660254037844386, 0.8660254037844386]')
    body = body.replace("orientations = [10, 20]", "orientations = [20]")
    study = write_study(tmp_path, body)
    rc = study_main(["study", str(study), "--out", str(tmp_path / "out"), "--scheduler", "synchronous", "--quiet",
                     "--no-figures"])
    captured = capsys.readouterr()
    assert rc == 1  # a study with a failed row exits non-zero (issue 27, item 4)
    assert "1 of 2 row(s) failed" in captured.err and "coincides" in captured.err
    rows = read_table(tmp_path / "out")
    assert rows[0]["error"] == "" and rows[0]["workspace_area"] > 0
    assert rows[1]["error"].startswith("MechanismError:") and "coincides with leg[1].origin" in rows[1]["error"]
    assert rows[1]["workspace_area"] is None and rows[1]["complete"] is False
    # a design error is a result: stored, not recomputed (unless asked)
    res = run_study(study, tmp_path / "out", scheduler="synchronous", progress=False, figures=False)
    assert (res.n_computed, res.n_reused, res.n_failed) == (0, 2, 1)
    res = run_study(study, tmp_path / "out", scheduler="synchronous", progress=False, figures=False,
                    retry_failed=True)
    assert (res.n_computed, res.n_reused, res.n_failed) == (1, 1, 1)


def test_areas_scale_as_s_squared(tmp_path):
    """Every length times s (rods, origins, attach points, grid step and bounds), EI and the
    (zero) load unchanged: areas x s^2, lengths x s, curvature x 1/s; the stiffness against a
    force (EI/L^3) x s^-3, against a moment (EI/L) x s^-1; the dimensionless indices (margin,
    homogeneous condition number with L_c = the mean rod length, manipulability) unchanged; the
    velocity ellipse (per unit homogenised input rate L_c/s) x s."""
    body = TINY.replace('"rod.length" = [1.0, 1.1]', '"scale" = [1.0, 2.0]').replace("[10, 20]", "[20]")
    res = run_study(write_study(tmp_path, body), tmp_path / "a", scheduler="synchronous", progress=False,
                    figures=False)
    one, two = res.rows
    assert one["error"] == two["error"] == ""
    for key in ("workspace_area", "singularity_free_area"):
        assert two[key] == pytest.approx(4.0 * one[key], rel=1e-9)
    assert two["inscribed_radius"] == pytest.approx(2.0 * one["inscribed_radius"], rel=1e-9)
    assert two["max_curvature"] == pytest.approx(0.5 * one["max_curvature"], rel=1e-6)
    assert two["n_aspects"] == one["n_aspects"] and two["input_span_1"] == pytest.approx(one["input_span_1"])
    law = {"stability_margin": 1.0, "cond": 1.0, "manipulability": 1.0, "force_stiffness": 2.0**-3,
           "moment_stiffness": 0.5, "velocity_minor": 2.0, "singularity_distance": 2.0}
    assert set(law) == set(INDEX_SUMMARIES)
    for name, factor in law.items():
        for stat in ("min", "mean", "max"):
            assert two[f"{stat}_{name}"] == pytest.approx(factor * one[f"{stat}_{name}"], rel=1e-6), (stat, name)
    # the same through a mechanism file scaled by hand (no 'scale' key): s = 2
    data = tomllib.loads((EXAMPLES / "unit_3rfr.toml").read_text())
    pts = ", ".join(f"[{2 * x!r}, {2 * y!r}]" for x, y in data["platform"]["attach"])
    legs = "".join(f'[[leg]]\nactuation = "revolute"\norigin = [{2 * leg["origin"][0]!r}, {2 * leg["origin"][1]!r}]\n'
                   for leg in data["leg"])
    (tmp_path / "big.toml").write_text(f"[rod]\nlength = 2.0\nEI = 1.0\n[platform]\nattach = [{pts}]\n{legs}")
    big = TINY.replace(f'mechanism = "{(EXAMPLES / "unit_3rfr.toml").as_posix()}"', 'mechanism = "big.toml"')
    big = big.replace('"rod.length" = [1.0, 1.1]', '"rod.EI" = [1.0]').replace("[10, 20]", "[20]")
    big = big.replace("step = 0.1", "step = 0.2")
    res2 = run_study(write_study(tmp_path, big, "big_study.toml"), tmp_path / "b", scheduler="synchronous",
                     progress=False, figures=False)
    assert res2.rows[0]["workspace_area"] == pytest.approx(two["workspace_area"], rel=1e-9)


def test_one_dimensional_figure_and_no_figures(tmp_path):
    body = TINY.replace("[10, 20]", "[20]")
    body = body.replace('name = "tiny"', 'name = "tiny"\nmetrics = ["max_cond", "workspace_area", "aspect_areas"]')
    res = run_study(write_study(tmp_path, body), tmp_path / "o", scheduler="synchronous", progress=False)
    assert [c for c, _ in res.columns][3:6] == ["workspace_area", "aspect_areas", "max_cond"]
    assert len(res.columns) == 3 + 3 + 4
    assert sorted(p.name for p in res.figures) == ["fig_max_cond.png", "fig_workspace_area.png"]  # no list figure


def _run_in_pty(args: list[str], timeout: float = 120.0) -> tuple[int, str]:
    """Run ``flexkin study ARGS`` in a subprocess whose stderr is a terminal; return its status
    and what it wrote there."""
    import os
    import pty
    import select
    import subprocess
    import sys

    import fcntl
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # a 120-column terminal
    code = "import sys; from flexkin.study.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL, stderr=slave,
                            stdin=subprocess.DEVNULL)
    os.close(slave)
    chunks, t_end = [], time.monotonic() + timeout
    try:
        while time.monotonic() < t_end:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
    finally:
        if proc.poll() is None:
            proc.kill()
        rc = proc.wait(timeout=10)
        os.close(master)
    return rc, b"".join(chunks).decode(errors="replace")


def test_progress_bar_on_a_terminal_counts_completed_rows(tmp_path):
    study = str(write_study(tmp_path, TINY))
    rc, err = _run_in_pty(["study", study, "--out", str(tmp_path / "a"), "--scheduler", "synchronous", "--no-figures"])
    assert rc == 0, err
    counts = [err.find(f"{k}/4") for k in range(5)]
    assert all(c >= 0 for c in counts) and counts == sorted(counts), err  # 0/4, 1/4, ... 4/4 in order
    one = write_study(tmp_path, TINY.replace("[10, 20]", "[20]").replace("[1.0, 1.1]", "[1.0]"), "one.toml")
    rc, err = _run_in_pty(["study", str(one), "--out", str(tmp_path / "b"), "--scheduler", "synchronous",
                           "--no-figures", "--quiet"])
    assert rc == 0 and "1/1" not in err and "row" not in err, err


def test_example_and_documented_study_files_are_valid(tmp_path):
    spec = load_study(EXAMPLES / "study_3rfr.toml")
    assert spec.n_tasks == 18 and spec.keys == ("rod.length", "platform.scale")
    assert spec.grid[1].values == (0.75, 1.0, 1.25)
    import re

    doc = (EXAMPLES.parent / "docs" / "study.md").read_text()
    blocks = [b for b in re.findall(r"```toml\n(.*?)```", doc, re.S) if "mechanism =" in b]
    assert len(blocks) >= 2
    shutil.copy(EXAMPLES / "unit_3rfr.toml", tmp_path / "unit_3rfr.toml")
    for k, block in enumerate(blocks):
        spec = load_study(write_study(tmp_path, block, f"doc{k}.toml"))
        assert spec.n_tasks in (24, 18)
