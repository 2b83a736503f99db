"""Issue 16's command line: ``flexkin refine`` and ``--model cosserat`` on ik/fk, the material keys
of the mechanism file ([rod] G/poisson, density, shear_coefficient; [environment] gravity)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

import flexkin
from flexkin.cli import main

EX = Path(__file__).resolve().parents[1] / "examples"
PROTO = EX / "prototype_3pfr.toml"


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def vertical(tmp_path_factory):
    """The prototype in a vertical plane: Nitinol density, Poisson ratio, gravity along -y."""
    text = PROTO.read_text(encoding="utf-8").replace("radius = 1.5e-3", "radius = 1.5e-3\npoisson = 0.33\ndensity = 6450")
    text += "\n[environment]\ngravity = [0.0, -9.81]\n"
    p = tmp_path_factory.mktemp("mech") / "proto_vertical.toml"
    p.write_text(text, encoding="utf-8")
    return p


def _platform_points(pose_deg, mech):
    return mech.platform.world((pose_deg[0], pose_deg[1], math.radians(pose_deg[2])))


def test_refine_ik_json_keeps_ids_and_closes_the_platform(capsys):
    code, out, err = run(capsys, "refine", PROTO, "--pose", "0", "0", "90", "--stable-only", "--json")
    assert code == 0
    d = json.loads(out)
    ref = flexkin.ik(flexkin.load_mechanism(PROTO), (0, 0, math.radians(90))).select(stable_only=True)
    assert [s["id"] for s in d["solutions"]] == [s.id for s in ref.solutions]
    assert d["problem"] == "refine-ik" and d["gravity"] is None
    A = math.pi * 1.5e-3 ** 2
    assert d["params"][0]["EA"] == pytest.approx(68e9 * A) and d["params"][0]["GA"] is None  # no G, no poisson
    mech = flexkin.load_mechanism(PROTO)
    for s in d["solutions"]:
        assert s["status"] == "refined" and s["verified"]
        assert s["pose"] == pytest.approx([0, 0, 90])  # IK: the pose is held
        # the refined rods end at the platform points of the refined pose
        B = _platform_points(s["pose"], mech)
        for i, rod in enumerate(s["rods"]):
            assert math.hypot(rod["tip"][0] - B[i][0], rod["tip"][1] - B[i][1]) < 1e-9
        # extension only (no shear, no weight): the strokes change by about the rods' elongation,
        # |n| L / EA at most (a few of them: the three rods share the platform)
        EA = d["params"][0]["EA"]
        bound = max(math.hypot(*rod["tip_force"]) for rod in s["rods"]) * 0.908 / EA
        shift = max(abs(v) for v in s["input_shift"])
        assert 0 < shift <= 3 * bound, (shift, bound)
        assert max(abs(rod["elongation"]) for rod in s["rods"]) <= 1.01 * bound


def test_gravity_from_the_file_pulls_the_fk_solutions_down(capsys, vertical, tmp_path):
    png = tmp_path / "refine.png"
    code, out, err = run(capsys, "refine", vertical, "--inputs", "0.025", "0.025", "0.025", "--stable-only",
                         "--json", "--plot", png)
    assert code == 0 and png.is_file() and str(png) in err
    d = json.loads(out)
    assert d["gravity"] == [0.0, -9.81]
    A = math.pi * 1.5e-3 ** 2
    assert d["params"][0]["mass_per_length"] == pytest.approx(6450 * A)
    assert d["line_loads"][0] == pytest.approx([0.0, -6450 * A * 9.81])
    assert d["params"][0]["GA"] == pytest.approx(68e9 / (2 * 1.33) * A)
    for s in d["solutions"]:
        assert s["status"] == "refined"
        assert s["pose"][1] < s["kirchhoff_pose"][1] - 1e-4  # the platform sags under the rods' weight
    # --gravity overrides the file: gravity along +x pushes it to +x instead
    code, out, _ = run(capsys, "refine", vertical, "--inputs", "0.025", "0.025", "0.025", "--stable-only",
                       "--gravity", "9.81", "0", "--json")
    for s in json.loads(out)["solutions"]:
        assert s["pose"][0] > s["kirchhoff_pose"][0] + 1e-4


def test_model_cosserat_adds_a_refined_object_per_solution(capsys):
    code, out, err = run(capsys, "ik", PROTO, "--pose", "0", "0", "60", "--stable-only", "--model", "cosserat",
                         "--json")
    assert code == 0
    d = json.loads(out)
    assert d["solutions"] and "refinement" in d
    for s in d["solutions"]:
        r = s["refined"]
        assert r is not None and r["status"] in ("refined", "fold", "failed")
        assert r["kirchhoff_inputs"] == pytest.approx(s["inputs"], abs=1e-9)
    code, out, err = run(capsys, "ik", PROTO, "--pose", "0", "0", "60", "--stable-only", "--model", "cosserat")
    assert code == 0 and "Cosserat refinement" in out and "du1 [m]" in out


@pytest.mark.parametrize("args, fragment", [
    (("ik", PROTO, "--pose", "0", "0", "90", "--gravity", "0", "-9.81"), "--model cosserat"),
    (("refine", EX / "unit_3rfr.toml", "--pose", "0.05", "0.02", "20"), "E and radius"),
    (("refine", PROTO, "--pose", "0", "0", "90", "--inputs", "0", "0", "0"), "not allowed with"),
    (("refine", PROTO), "--pose"),
])
def test_refine_bad_input_is_one_line(capsys, args, fragment):
    code, out, err = run(capsys, *args)
    assert code == 2 and fragment in err and "Traceback" not in err
