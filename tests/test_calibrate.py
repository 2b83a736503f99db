"""Calibration (issue 28): parameters of a built prototype from measured (inputs, pose) rows.

Synthetic truth: a perturbed mechanism (input offsets of +-5 mm, E by +8 %, an origin by 3 mm) is
measured by the INDEPENDENT shooting oracles of this directory (``calibration_truth``), noise is
added, and the fit from the nominal mechanism must recover the truth within 3 standard errors;
over seeds the 95 % intervals must cover the truth at about the nominal rate (50 seeds in the slow
run, 6 in the default run).  The analytic parameter Jacobian (implicit-function theorem) is
checked against central differences of the followed branches to 1e-5 relative.
"""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

import flexkin
from flexkin.calibration import FitKeyError, calibrate
from flexkin.calibration.engine import Model, match_rows, prepare_rows
from flexkin.calibration.params import parse_fit_keys, values_of
from flexkin.cli import main
from flexkin.io.measurements import MeasurementError, measurements_from_rows, parse_measurements

from calibration_truth import Truth, noisy_csv_rows, true_rows


# ---- synthetic truth (computed once per module by the oracles) ---------------------------
F_REF = 0.33  # N, EI/L^2 of the prototype
TRUTH = Truth(offsets=(0.005, -0.004, 0.003), E_factor=1.08, origin_shift=((0.0, 0.003), (0.0, 0.0), (0.0, 0.0)))
FIT = ["leg[*].offset", "rod.E", "leg[1].origin_y"]
SIGMA_XY, SIGMA_TH, SIGMA_U = 2e-4, 0.1, 1e-4


@pytest.fixture(scope="module")
def proto(examples_dir):
    return flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")


@pytest.fixture(scope="module")
def truth_rows(proto):
    """Noise-free rows of the perturbed prototype: 5 IK and 3 FK rows, loaded (E shows only under load)."""
    ik_poses = [(0.0, 0.0, math.radians(t)) for t in (60, 90, 120)] + [(0.05, -0.03, math.radians(80)),
                                                                      (-0.04, 0.05, math.radians(100))]
    fk_poses = [(0.03, 0.02, math.radians(90)), (-0.03, -0.02, math.radians(75)), (0.0, 0.04, math.radians(110))]
    loads = [(0, 0, 0), (0.6 * F_REF, 0, 0), (0, -0.6 * F_REF, 0), (0.4 * F_REF, 0.4 * F_REF, 0.0),
             (0, 0, 0.09 * F_REF), (0, 0.6 * F_REF, 0), (-0.6 * F_REF, 0, 0), (0.3 * F_REF, -0.4 * F_REF, 0.0)]
    return true_rows(proto, TRUTH, ik_poses, fk_poses, loads)


def _true_values(proto):
    return {"leg[1].offset": TRUTH.offsets[0], "leg[2].offset": TRUTH.offsets[1], "leg[3].offset": TRUTH.offsets[2],
            "rod.E": proto.legs[0].rod.E * TRUTH.E_factor, "leg[1].origin_y": proto.legs[0].origin[1] + 0.003}


def _fit_seed(proto, truth_rows, seed, absolute_sigma=True, loo=False):
    data = noisy_csv_rows(proto, truth_rows, np.random.default_rng(seed), SIGMA_XY, SIGMA_TH, SIGMA_U)
    return calibrate(proto, data, FIT, max_mode=1, absolute_sigma=absolute_sigma, loo=loo)


def test_synthetic_truth_recovered_within_three_standard_errors(proto, truth_rows):
    res = _fit_seed(proto, truth_rows, seed=1, absolute_sigma=False, loo=True)
    assert res.complete and res.identifiable, res.message
    assert not res.outliers
    truth = _true_values(proto)
    for p in res.parameters:
        assert p.stderr is not None and p.stderr > 0
        assert abs(p.value - truth[p.key]) <= 3.0 * p.stderr, (p.key, p.value, truth[p.key], p.stderr)
    # the offsets are known far better than they were wrong
    for k in ("leg[1].offset", "leg[2].offset", "leg[3].offset"):
        assert res.estimate(k).stderr < 1e-3
    # the residuals drop to the noise level, before: millimetres
    assert res.rms_before["u"] > 3e-3 and res.rms_after["u"] < 3 * SIGMA_U
    assert res.rms_before["xy"] > 3e-3 and res.rms_after["xy"] < 3 * SIGMA_XY
    assert res.loo_rms["xy"] < 5 * SIGMA_XY and res.loo_rms["u"] < 5 * SIGMA_U
    # correlation matrix: symmetric, unit diagonal, entries in [-1, 1]
    C = res.correlation
    assert np.allclose(C, C.T) and np.allclose(np.diag(C), 1.0) and np.all(np.abs(C) <= 1 + 1e-9)
    js = res.to_dict()
    json.dumps(js, allow_nan=False)
    assert {"parameters", "rms_before", "rms_after", "rows", "identifiable"} <= js.keys()
    assert {"key", "initial", "value", "stderr"} <= js["parameters"][0].keys()
    assert {"xy", "theta_deg", "u"} <= js["rms_before"].keys()


def _coverage(proto, truth_rows, seeds):
    truth = _true_values(proto)
    hits = total = 0
    for seed in seeds:
        res = _fit_seed(proto, truth_rows, seed)
        assert not res.outliers, [r.reason for r in res.outliers]
        for p in res.parameters:
            total += 1
            hits += p.ci95[0] <= truth[p.key] <= p.ci95[1]
    return hits / total, total


def test_interval_coverage_small(proto, truth_rows):
    """6 seeds x 5 parameters: at least 80 % of the 95 % intervals cover the truth."""
    rate, n = _coverage(proto, truth_rows, range(100, 106))
    assert rate >= 0.8, (rate, n)


@pytest.mark.slow
def test_interval_coverage_50_seeds(proto, truth_rows):
    """50 seeds x 5 parameters = 250 intervals: the rate is 95 % +- 1.4 % (binomial sd)."""
    rate, n = _coverage(proto, truth_rows, range(200, 250))
    assert 0.90 <= rate <= 0.99, (rate, n)


# ---- the parameter Jacobian against central differences ----------------------------------
@pytest.mark.parametrize("name, keys, pose, load", [
    ("prototype_3pfr.toml", ["leg[*].offset", "leg[*].origin", "leg[*].angle", "rod.length", "rod.E",
                             "platform.attach"], (0.02, -0.01, math.radians(85)), (0.05, -0.03, 0.002)),
    ("mixed_legs.toml", ["leg[*].offset", "leg[*].origin", "leg[*].angle", "leg[*].length", "leg[*].E",
                         "platform.attach[2]"], (0.0, 0.0, math.radians(6)), None),
    ("mixed_clamped.toml", ["leg[*].offset", "leg[2].origin", "leg[*].angle", "leg[1].length", "leg[3].EI",
                            "platform.attach[1]"], (0.02, -0.05, math.radians(5.73)), None),
])
def test_parameter_jacobian_matches_central_differences(examples_dir, name, keys, pose, load):
    """d(prediction)/d(parameter) by the implicit-function theorem vs central differences of the
    branch followed to theta +- h (Newton-converged), for an IK row and an FK row."""
    mech = flexkin.load_mechanism(examples_dir / name)
    w = np.array(mech.load if load is None else load, float)
    ik = flexkin.ik(mech, pose, w, max_mode=1)
    sol = [s for s in ik.solutions if s.stable is True][0]
    u_disp = [float(leg.to_display(u)) for leg, u in zip(mech.legs, sol.inputs)]
    rec = {"x": pose[0], "y": pose[1], "theta_deg": math.degrees(pose[2]), "u1": u_disp[0], "u2": u_disp[1],
           "u3": u_disp[2], "fx": w[0], "fy": w[1], "mz": w[2], "solution": sol.id}
    meas = measurements_from_rows([{**rec, "kind": "ik"}, {**rec, "kind": "fk"}])
    params = parse_fit_keys(keys, mech)
    assert len(params) >= 10
    theta0 = values_of(mech, params)
    rows = prepare_rows(mech, meas.rows)
    # both rows start from the same equilibrium (an IK solution is an FK solution of its inputs)
    from flexkin.calibration.engine import Match
    m = Match(True, "", sol.id, sol.mode_label, sol.x.copy(), np.array(sol.charts), True, 1, 0.0)
    model = Model(mech, params, theta0, rows, [m, m])
    worst = 0.0
    for r in range(2):
        D = model.tangent(theta0, r, sol.x, np.array(sol.charts))[-3:]          # (3, k)
        for k in range(len(params)):
            h = 1e-4 * model.scale[k]
            preds = []
            for sgn in (1.0, -1.0):
                th = theta0.copy()
                th[k] += sgn * h
                got = model.follow(r, sol.x, np.array(sol.charts), theta0, th)
                assert got is not None
                preds.append(model.predict_row(r, got[0]))
            fd = (preds[0] - preds[1]) / (2 * h)
            ref = max(float(np.max(np.abs(fd))), 1e-300)
            if ref * model.scale[k] < 1e-9 * max(1.0, float(np.max(np.abs(D * model.scale)))):
                assert np.max(np.abs(D[:, k])) * model.scale[k] < 1e-7  # a parameter the row does not see
                continue
            err = float(np.max(np.abs(fd - D[:, k]))) / ref
            worst = max(worst, err)
            assert err < 1e-5, (name, r, params[k].name, err, fd, D[:, k])
    assert worst < 1e-5
    print(f"{name}: {len(params)} parameters, worst relative error {worst:.2e}")


# ---- identifiability, outliers -----------------------------------------------------------
def test_non_identifiable_pair_detected_and_named(examples_dir):
    """Leg 1's guide runs along x: its input offset and origin_x move the clamp the same way."""
    res = calibrate(examples_dir / "prototype_3pfr.toml", examples_dir / "prototype_measurements.csv",
                    ["leg[1].offset", "leg[1].origin"], loo=False)
    assert not res.identifiable
    bad = [c for c in res.combinations if not c.identifiable]
    assert len(bad) == 1
    assert "leg[1].offset" in bad[0].text and "leg[1].origin_x" in bad[0].text
    assert "leg[1].origin_y" not in bad[0].text
    coef = dict(zip([p.key for p in res.parameters], bad[0].coefficients))
    assert coef["leg[1].offset"] == pytest.approx(-coef["leg[1].origin_x"], rel=1e-6)  # offset + x shift cancel
    assert res.estimate("leg[1].offset").stderr is None and res.estimate("leg[1].origin_x").stderr is None
    assert res.estimate("leg[1].origin_y").stderr is not None
    # the unseen combination (offset up, origin_x down) stays where it started: both moved alike
    off, ox = res.estimate("leg[1].offset"), res.estimate("leg[1].origin_x")
    assert off.value - off.initial == pytest.approx(ox.value - ox.initial, abs=1e-9)
    assert abs(off.value - off.initial) > 1e-3
    assert "not identifiable" in res.message and "not identifiable".upper() in res.table().upper()


def test_stiffness_not_identifiable_without_load(examples_dir):
    """Unloaded, a uniform change of E changes no equilibrium: the prototype's data cannot see E."""
    res = calibrate(examples_dir / "prototype_3pfr.toml", examples_dir / "prototype_measurements.csv",
                    ["leg[*].offset", "rod.E"], loo=False)
    assert not res.identifiable
    assert res.estimate("rod.E").stderr is None and res.estimate("rod.E").value == pytest.approx(68.0e9)
    assert [c.text for c in res.combinations if not c.identifiable] == ["1 rod.E"]
    assert res.estimate("leg[1].offset").stderr is not None


PROTO_ROWS = [
    "kind,u1,u2,u3,x,y,theta_deg,solution",
    "fk,0.025,0.025,0.025,-0.002,-0.002,99.0,",
    "fk,0.025,0.025,0.025,0.008,-0.001,-84.0,",
    "ik,-0.017,-0.013,-0.018,0.0,0.0,60.0,",
    "ik,0.019,0.018,0.013,0.0,0.0,90.0,",
    "ik,0.051,0.051,0.040,0.0,0.0,120.0,",
]


def test_wrong_branch_and_unreachable_rows_flagged(proto):
    fk0 = flexkin.fk(proto, (0.025, 0.025, 0.025))
    unstable = [s for s in fk0.solutions if s.stable is False][0]
    p = unstable.pose
    extra = [
        f"fk,0.025,0.025,0.025,{p[0]:.6f},{p[1]:.6f},{math.degrees(p[2]):.4f},",   # on an unstable branch
        "ik,0,0,0,0.6,0.0,90.0,",                                                 # outside the workspace
        f"fk,0.025,0.025,0.025,0.0,0.0,90.0,{unstable.id}",                       # names an unstable solution
        "fk,0.025,0.025,0.025,0.0,0.0,90.0,99",                                   # names no solution
    ]
    res = calibrate(proto, parse_measurements("\n".join(PROTO_ROWS + extra), "bad.csv"), ["leg[*].offset"], loo=False)
    flagged = {r.index: r.reason for r in res.rows if r.outlier}
    assert set(flagged) == {6, 7, 8, 9}
    assert flagged[6].startswith("wrong branch") and "unstable" in flagged[6]
    assert flagged[7].startswith("unreachable")
    assert "unstable" in flagged[8] and "named solution" in flagged[8]
    assert "does not exist" in flagged[9]
    # the outliers were not fitted: same estimates as without them
    ref = calibrate(proto, parse_measurements("\n".join(PROTO_ROWS), "ok.csv"), ["leg[*].offset"], loo=False)
    for a, b in zip(res.parameters, ref.parameters):
        assert a.value == pytest.approx(b.value, abs=1e-9)
    assert "4 outlier rows" in res.message


def test_gross_error_row_flagged_after_fit(proto, truth_rows):
    data = noisy_csv_rows(proto, truth_rows, np.random.default_rng(5), SIGMA_XY, SIGMA_TH, SIGMA_U)
    data[1] = {**data[1], "u2": data[1]["u2"] + 0.02}   # 20 mm = 200 sigma on one input
    res = calibrate(proto, data, FIT, max_mode=1, loo=False)
    assert [r.index for r in res.outliers] == [2]
    assert res.outliers[0].reason.startswith("gross error")
    truth = _true_values(proto)
    for p in res.parameters:
        assert abs(p.value - truth[p.key]) <= 4.0 * p.stderr


# ---- the offset (SPEC §4) ------------------------------------------------------------------
def test_offset_shifts_inputs_and_poses(examples_dir):
    text = (examples_dir / "mixed_legs.toml").read_text()
    raw = tomllib.loads(text)
    for t, o in zip(raw["leg"], (0.004, 2.5, -0.003)):
        t["offset"] = o
    mech0 = flexkin.mechanism_from_dict(tomllib.loads(text))
    mech1 = flexkin.mechanism_from_dict(raw)
    off = np.array([leg.offset for leg in mech1.legs])
    assert off[1] == pytest.approx(math.radians(2.5)) and mech1.legs[1].actuation == "revolute"
    pose = (0.0, 0.0, math.radians(6))
    a = flexkin.ik(mech0, pose, max_mode=1)
    b = flexkin.ik(mech1, pose, max_mode=1)
    assert len(a.solutions) == len(b.solutions) > 0
    for s0, s1 in zip(a.solutions, b.solutions):
        assert np.allclose(np.array(s1.inputs) + off, s0.inputs, atol=1e-10)
    u = np.array(b.solutions[0].inputs)
    fk1 = flexkin.fk(mech1, u, max_mode=1)
    assert any(np.allclose(s.pose, pose, atol=1e-9) for s in fk1.solutions)
    assert "input zero offsets" in mech1.summary()


def test_offset_study_key(examples_dir):
    from flexkin.study.grid import apply_design, parse_key

    raw = tomllib.loads((examples_dir / "prototype_3pfr.toml").read_text())
    mech = flexkin.mechanism_from_dict(raw)
    assert parse_key("leg[2].offset").prop == "offset"
    d = apply_design(raw, mech, {"leg.offset": 0.002, "leg[2].offset": -0.001})
    m = flexkin.mechanism_from_dict(d)
    assert [leg.offset for leg in m.legs] == [0.002, -0.001, 0.002]


# ---- files, keys, command line -------------------------------------------------------------
@pytest.mark.parametrize("text, expect", [
    ("kind,u1,u2,u3,x,y\nfk,1,2,3,0,0", "missing column theta_deg"),
    ("kind,u1,u2,u3,x,y,theta_deg,sigma_xyz\nfk,1,2,3,0,0,0,1", "unknown column 'sigma_xyz' (did you mean 'sigma_xy'?)"),
    ("kind,u1,u2,u3,x,y,theta_deg\n# c\n\nfk,1,2,3,0,0,0\nxk,1,2,3,0,0,0", "row 2 (line 5): kind:"),
    ("kind,u1,u2,u3,x,y,theta_deg\nik,1,abc,3,0,0,0", "row 1 (line 2): u2: expected a number, got 'abc'"),
    ("kind,u1,u2,u3,x,y,theta_deg,sigma_u\nik,1,2,3,0,0,0,-1", "row 1 (line 2): sigma_u: must be > 0"),
    ("kind,u1,u2,u3,x,y,theta_deg,solution\nik,1,2,3,0,0,0,1.5", "solution: expected a solution id"),
    ("kind,u1,u2,u3,x,y,theta_deg\nik,1,2,3,0,0", "row 1 (line 2): theta_deg: missing"),
    ("kind,u1,u2,u3,x,y,theta_deg\nik,1,2,3,0,0,nan", "expected a finite number"),
    ("# only a comment\n", "no header row"),
])
def test_measurement_file_errors(text, expect):
    with pytest.raises(MeasurementError) as e:
        parse_measurements(text, "m.csv")
    assert expect in str(e.value) and str(e.value).startswith("m.csv: ") and "\n" not in str(e.value)


def test_measurement_file_defaults_and_comments():
    m = parse_measurements("# header comment\nkind, u1,u2,u3,x,y,theta_deg,fx\n\nfk,1,2,3,0.1,0.2,30,  # c\n"
                           "ik,1,2,3,0,0,0,0.5\n", "m.csv")
    assert len(m) == 2 and m.rows[0].load is None and m.rows[1].load == (0.5, 0.0, 0.0)
    assert m.rows[1].line == 5 and m.rows[0].sigma_xy is None


@pytest.mark.parametrize("keys, expect", [
    (["leg[4].offset"], "no leg 4"),
    (["leg[1].angel"], "unknown parameter"),
    (["leg.origin"], "cannot be shared"),
    (["rod.E", "leg[2].E"], "already fitted"),
    (["leg[1].offset", "leg[*].offset"], "already fitted"),
    ([], "at least one"),
])
def test_fit_key_errors(proto, keys, expect):
    with pytest.raises(FitKeyError) as e:
        parse_fit_keys(keys, proto)
    assert expect in str(e.value)


def test_cli_calibrate_prototype(examples_dir, tmp_path, capsys):
    mech = examples_dir / "prototype_3pfr.toml"
    data = examples_dir / "prototype_measurements.csv"
    out = tmp_path / "calibrated.toml"
    rc = main(["calibrate", str(mech), "--data", str(data), "--fit", "leg[*].offset", "--out", str(out),
               "--report", str(tmp_path / "rep")])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert "leg[3].offset" in cap.out and "leave-one-out" in cap.out and "RMS over the fitted rows" in cap.out
    assert f"written: {out}" in cap.err
    for f in ("report.md", "report.html", "calibration.png", "calibration.json", "calibrated.toml"):
        assert (tmp_path / "rep" / f).is_file()
    # the calibrated file differs from the input only in the fitted keys
    a, b = tomllib.loads(mech.read_text()), tomllib.loads(out.read_text())
    offs = [t.pop("offset") for t in b["leg"]]
    assert a == b
    rc = main(["calibrate", str(mech), "--data", str(data), "--fit", "leg[*].offset", "--json", "--no-loo"])
    js = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert [p["value"] for p in js["parameters"]] == pytest.approx(offs, abs=1e-9)
    cal = flexkin.load_mechanism(out)
    assert [leg.offset for leg in cal.legs] == pytest.approx(offs)
    # re-fitting from the calibrated file changes nothing
    res = calibrate(cal, data, ["leg[*].offset"], loo=False)
    assert [p.value for p in res.parameters] == pytest.approx(offs, abs=1e-7)


@pytest.mark.parametrize("args, expect", [
    (["--fit", "leg[9].offset"], "no leg 9"),
    (["--fit", "leg[*].offset", "--data", "nonexistent.csv"], "file not found"),
    (["--fit", "leg[*].offset", "--loss", "l2"], "invalid choice"),
])
def test_cli_calibrate_bad_input(examples_dir, capsys, args, expect):
    argv = ["calibrate", str(examples_dir / "prototype_3pfr.toml")]
    if "--data" not in args:
        argv += ["--data", str(examples_dir / "prototype_measurements.csv")]
    rc = main(argv + args)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and expect in err[-1]


def test_calibrated_toml_keeps_comments_and_edits_arrays(examples_dir, tmp_path):
    from flexkin.calibration.toml_edit import calibrated_toml

    text = (examples_dir / "prototype_3pfr.toml").read_text()
    raw = tomllib.loads(text)
    mech = flexkin.mechanism_from_dict(raw)
    params = parse_fit_keys(["leg[2].origin", "platform.attach[3]", "rod.E", "leg[1].angle"], mech, raw)
    vals = [0.78, -0.46, 0.001, 0.05, 70e9, 1.5]
    new = calibrated_toml(text, raw, params, vals, "note")
    assert "# Leg placement and the zero of rho were inferred" in new and "written from the parsed" not in new
    d = tomllib.loads(new)
    assert d["leg"][1]["origin"] == [0.78, -0.46] and d["platform"]["attach"][2] == [0.001, 0.05]
    assert d["rod"]["E"] == 70e9 and d["leg"][0]["angle"] == 1.5
    d["leg"][1]["origin"], d["platform"]["attach"][2] = raw["leg"][1]["origin"], raw["platform"]["attach"][2]
    d["rod"]["E"], d["leg"][0]["angle"] = raw["rod"]["E"], raw["leg"][0]["angle"]
    assert d == raw


def test_matching_prefers_nearest_stable_branch(proto):
    """Table 1's two rows at the same inputs are matched to the two different stable poses."""
    meas = parse_measurements("\n".join(PROTO_ROWS[:3]), "t1.csv")
    rows = prepare_rows(proto, meas.rows)
    m = match_rows(proto, rows)
    assert m[0].ok and m[1].ok and m[0].solution != m[1].solution
    th = [math.degrees(proto_pose[2]) for proto_pose in (m[0].x[-6:-3], m[1].x[-6:-3])]
    assert th[0] == pytest.approx(90.05, abs=0.05) and th[1] == pytest.approx(-76.5, abs=0.1)


# ---- a vertical prototype: the Cosserat model with weight --------------------------------
@pytest.mark.slow
def test_cosserat_model_keeps_the_sag_out_of_the_geometry(examples_dir):
    """The prototype stood up in a vertical plane sags by a few mm under its own weight.  Measured
    (the independent discrete-beam oracle, Richardson-extrapolated) with true input offsets and no
    noise, the Cosserat fit recovers the offsets; the weightless Kirchhoff fit absorbs the sag into
    wrong offsets, by several of its own standard errors."""
    from flexkin.cosserat.params import cosserat_setup

    from calibration_truth import cosserat_fk_truth

    raw = tomllib.loads((examples_dir / "prototype_3pfr.toml").read_text())
    raw["rod"]["G"] = 1.8e5 / (math.pi * 1.5e-3**2)
    raw["rod"]["density"] = 6450.0
    raw["environment"] = {"gravity": [0.0, -9.81]}
    nom = flexkin.mechanism_from_dict(raw)
    off = np.array([0.004, -0.003, 0.005])
    params, grav = cosserat_setup(nom)
    rows = []
    for u in [(0.025, 0.025, 0.025), (0.02, 0.03, 0.025), (0.03, 0.02, 0.028), (0.015, 0.025, 0.035)]:
        p, gap = cosserat_fk_truth(nom, np.array(u) + off, math.radians(90), params, grav)
        assert gap < 1e-5   # the oracle and flexkin's refinement agree on the truth
        rows.append({"kind": "fk", "u1": u[0], "u2": u[1], "u3": u[2], "x": p[0], "y": p[1],
                     "theta_deg": math.degrees(p[2]), "sigma_xy": SIGMA_XY, "sigma_theta_deg": SIGMA_TH})
    cos = calibrate(nom, rows, ["leg[*].offset"], model="cosserat", loo=False, max_mode=1, absolute_sigma=True)
    kir = calibrate(nom, rows, ["leg[*].offset"], loo=False, max_mode=1, absolute_sigma=True)
    assert cos.model == "cosserat" and "gravity is ignored" in kir.message
    for p, o in zip(cos.parameters, off):
        assert abs(p.value - o) < 1e-5           # exact data: the truth, to the oracle's accuracy
    bias = max(abs(p.value - o) / p.stderr for p, o in zip(kir.parameters, off))
    assert bias > 5.0                            # the sag went into the offsets


def test_robust_loss_bounds_a_gross_error(proto, truth_rows):
    """soft_l1 with a 3-sigma margin: one 20 mm input error barely moves the estimates (the row is
    still flagged afterwards); bad loss names are refused."""
    data = noisy_csv_rows(proto, truth_rows, np.random.default_rng(7), SIGMA_XY, SIGMA_TH, SIGMA_U)
    data[2] = {**data[2], "u1": data[2]["u1"] - 0.02}
    res = calibrate(proto, data, FIT, max_mode=1, loo=False, loss="soft_l1", f_scale=3.0)
    assert res.loss == "soft_l1" and [r.index for r in res.outliers] == [3]
    truth = _true_values(proto)
    for p in res.parameters:
        assert abs(p.value - truth[p.key]) <= 4.0 * p.stderr
    with pytest.raises(ValueError, match="loss"):
        calibrate(proto, data, FIT, loss="l1")
    with pytest.raises(ValueError, match="model"):
        calibrate(proto, data, FIT, model="fem")
