"""Tests of flexkin.mechanism (model, TOML loader, builders) and flexkin.plot.mechanism."""

from __future__ import annotations

import copy
import dataclasses
import math
import random
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flexkin.errors import FlexkinWarning, MechanismError
from flexkin.mechanism import (
    ACTUATIONS,
    Leg,
    Mechanism,
    Platform,
    Rod,
    load_mechanism,
    mechanism_from_dict,
    symmetric_mechanism,
)

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PROTOTYPE = EXAMPLES / "prototype_3pfr.toml"


def _rot(angle: float, v) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    v = np.asarray(v, dtype=float)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _same_angle(a: float, b: float, tol: float = 1e-12) -> bool:
    return abs(math.remainder(a - b, 2 * math.pi)) < tol


# ---------------------------------------------------------------------------------------
# errors
# ---------------------------------------------------------------------------------------
def test_error_classes():
    assert issubclass(MechanismError, ValueError)
    assert issubclass(FlexkinWarning, UserWarning)


# ---------------------------------------------------------------------------------------
# the prototype file
# ---------------------------------------------------------------------------------------
def test_prototype_values():
    m = load_mechanism(PROTOTYPE)
    assert m.name == "3-PFR prototype"
    assert m.kind == "3-PFR"
    assert m.source == str(PROTOTYPE)
    # EI of a circular Nitinol rod, E = 68 GPa, r = 1.5 mm (file values)
    EI = 68e9 * math.pi * 1.5e-3**4 / 4
    assert EI == pytest.approx(0.27037, rel=1e-4)  # the value quoted in SPEC §3's comment
    for leg in m.legs:
        assert leg.actuation == "prismatic"
        assert leg.rod.EI == pytest.approx(EI, rel=1e-14)
        assert leg.rod.length == 0.908
        assert leg.rod.radius == 1.5e-3
        assert leg.rod.E == 68e9
        assert leg.range is None
    assert [leg.angle for leg in m.legs] == pytest.approx([0.0, 2 * math.pi / 3, 4 * math.pi / 3], abs=1e-15)
    assert m.legs[0].origin == (-0.789, -0.45)
    assert m.legs[1].origin == (0.784211431703, -0.458294043586)
    assert m.legs[2].origin == (0.004788568297, 0.908294043586)
    assert m.platform.attach == (
        (-0.045, -0.025980762113533),
        (0.045, -0.025980762113533),
        (0.0, 0.051961524227066),
    )
    assert m.platform.size == pytest.approx(0.09, rel=1e-12)
    assert m.load == (0.0, 0.0, 0.0)
    assert m.max_strain is None
    assert m.length_scale == pytest.approx(0.908)
    assert m.EI_scale == pytest.approx(EI)
    s = m.summary()
    assert "3-PFR prototype" in s and "prismatic" in s and "0.908" in s


def test_prototype_is_scaled_shifted_builder_arrangement():
    """The prototype = symmetric_mechanism('prismatic') scaled to base radius 0.9 m, platform
    radius 0.09/sqrt(3) m, with each guide origin moved back along its own guide by the same
    distance (9.577 mm): same leg ordering, same guide directions, C3-symmetric."""
    proto = load_mechanism(PROTOTYPE)
    b = symmetric_mechanism("prismatic", base_radius=0.9, platform_radius=0.09 / math.sqrt(3), length=0.908)
    shifts = []
    for lp, lb in zip(proto.legs, b.legs):
        assert _same_angle(lp.angle, lb.angle)
        delta = np.subtract(lp.origin, lb.origin)
        d = lb.direction
        # the offset is along the guide ...
        assert abs(d[0] * delta[1] - d[1] * delta[0]) < 1e-9
        shifts.append(float(delta @ d))
    # ... and the same for the three legs (a shift of the zero of rho)
    assert shifts == pytest.approx([shifts[0]] * 3, abs=1e-9)
    assert shifts[0] == pytest.approx(-(0.789 - 0.9 * math.sqrt(3) / 2), abs=1e-12)
    assert shifts[0] == pytest.approx(-0.009577, abs=1e-6)
    assert np.allclose(proto.platform.b, b.platform.b, atol=1e-12)


# ---------------------------------------------------------------------------------------
# Platform and Leg geometry
# ---------------------------------------------------------------------------------------
def test_platform_world_hand_computation():
    p = Platform(attach=((-0.045, -0.03), (0.045, -0.03), (0.0, 0.06)))
    # theta = 90 deg: Rot(90)(bx, by) = (-by, bx)
    B = p.world([0.1, -0.2, math.pi / 2])
    assert B.shape == (3, 2)
    expected = np.array([[0.1 + 0.03, -0.2 - 0.045], [0.1 + 0.03, -0.2 + 0.045], [0.1 - 0.06, -0.2 + 0.0]])
    assert np.allclose(B, expected, atol=1e-15)
    # theta = 30 deg, written out: x + cos*bx - sin*by, y + sin*bx + cos*by
    c, s = math.sqrt(3) / 2, 0.5
    B = p.world([0.0, 0.0, math.pi / 6])
    assert B[0] == pytest.approx([c * -0.045 - s * -0.03, s * -0.045 + c * -0.03])
    assert B[2] == pytest.approx([-s * 0.06, c * 0.06])
    # theta = 0 is a translation
    assert np.allclose(p.world([1.0, 2.0, 0.0]), p.b + [1.0, 2.0])


def test_platform_world_vectorised():
    p = Platform(attach=((-0.045, -0.03), (0.045, -0.03), (0.0, 0.06)))
    rng = np.random.default_rng(1)
    poses = rng.normal(size=(4, 5, 3))
    B = p.world(poses)
    assert B.shape == (4, 5, 3, 2)
    for idx in [(0, 0), (3, 4), (2, 1)]:
        assert np.allclose(B[idx], p.world(poses[idx]), atol=1e-15)
    # rigid motion: pairwise distances preserved
    d01 = np.linalg.norm(B[..., 0, :] - B[..., 1, :], axis=-1)
    assert np.allclose(d01, np.linalg.norm(p.b[0] - p.b[1]))
    with pytest.raises(ValueError):
        p.world([0.0, 0.0])


def test_clamp_prismatic_vectorised():
    leg = Leg("prismatic", (1.0, 2.0), math.radians(30), Rod(length=0.9, EI=0.3))
    u = np.array([[0.0, 0.1, -0.2], [1.0, 2.0, 3.0]])
    A, alpha, L = leg.clamp(u)
    assert A.shape == (2, 3, 2) and alpha.shape == (2, 3) and L.shape == (2, 3)
    assert A[0, 1] == pytest.approx([1.0 + 0.1 * math.sqrt(3) / 2, 2.0 + 0.05])
    assert A[1, 2] == pytest.approx([1.0 + 3 * math.sqrt(3) / 2, 2.0 + 1.5])
    assert np.all(alpha == math.radians(30))
    assert np.all(L == 0.9)
    A0, a0, L0 = leg.clamp(0.5)  # scalar input
    assert A0.shape == (2,) and a0.shape == () and L0.shape == ()


def test_clamp_revolute_vectorised():
    leg = Leg("revolute", (0.3, -0.4), 0.0, Rod(length=0.8, EI=1.0))
    u = np.linspace(-1, 1, 7)
    A, alpha, L = leg.clamp(u)
    assert A.shape == (7, 2)
    assert np.all(A == [0.3, -0.4])
    assert np.array_equal(alpha, u)
    assert np.all(L == 0.8)
    A[0, 0] = 99.0  # returned arrays are independent copies
    assert leg.clamp(u)[0][0, 0] == 0.3


def test_clamp_length_vectorised():
    leg = Leg("length", (0.0, 1.0), math.radians(270), Rod(length=None, EI=1.0))
    u = np.array([[0.2], [0.7]])
    A, alpha, L = leg.clamp(u)
    assert A.shape == (2, 1, 2)
    assert np.all(A == [0.0, 1.0])
    assert np.allclose(alpha, math.radians(270))
    assert np.array_equal(L, u)


def test_display_units_round_trip():
    rev = Leg("revolute", (0.0, 0.0), 0.0, Rod(length=1.0, EI=1.0))
    pri = Leg("prismatic", (0.0, 0.0), 0.0, Rod(length=1.0, EI=1.0))
    ln = Leg("length", (0.0, 0.0), 0.0, Rod(length=None, EI=1.0))
    assert rev.input_unit == "deg" and pri.input_unit == "m" and ln.input_unit == "m"
    assert rev.to_display(math.pi / 2) == pytest.approx(90.0)
    assert rev.from_display(180.0) == pytest.approx(math.pi)
    assert isinstance(rev.to_display(1.0), float)
    v = np.array([-170.0, 0.0, 33.3, 359.0])
    assert np.allclose(rev.to_display(rev.from_display(v)), v, rtol=1e-15, atol=1e-12)
    assert np.array_equal(pri.to_display(v), v) and np.array_equal(pri.from_display(v), v)
    assert ln.to_display(0.25) == 0.25


def test_in_range():
    leg = Leg("revolute", (0.0, 0.0), 0.0, Rod(length=1.0, EI=1.0), range=(0.0, math.pi))
    assert leg.in_range([-0.1, 0.0, 1.0, math.pi, 4.0]).tolist() == [False, True, True, True, False]
    free = dataclasses.replace(leg, range=None)
    assert free.in_range([1e9]).tolist() == [True]


def test_model_validation_direct():
    with pytest.raises(MechanismError):
        Rod(length=1.0, EI=0.0)
    with pytest.raises(MechanismError):
        Rod(length=-1.0, EI=1.0)
    with pytest.raises(MechanismError):
        Rod(length=1.0, EI=float("nan"))
    with pytest.raises(MechanismError):
        Rod(length=True, EI=1.0)  # bool is not a number
    with pytest.raises(MechanismError):
        Leg("telescopic", (0, 0), 0.0, Rod(1.0, 1.0))  # type: ignore[arg-type]
    with pytest.raises(MechanismError):
        Leg("prismatic", (0, 0), 0.0, Rod(None, 1.0))  # needs a rod length
    with pytest.raises(MechanismError):
        Leg("prismatic", (0, 0), 0.0, Rod(1.0, 1.0), range=(1.0, 0.5))
    with pytest.raises(MechanismError, match="coincide"):
        Platform(attach=((0, 0), (0, 0), (1, 1)))
    with pytest.raises(MechanismError, match="collinear"):
        Platform(attach=((0, 0), (1, 1), (2, 2)))
    r = Rod.circular(1.0, E=68e9, radius=1.5e-3)
    assert r.EI == pytest.approx(68e9 * math.pi * 1.5e-3**4 / 4)
    assert r.strain([2.0, -4.0]) == pytest.approx([3e-3, 6e-3])
    with pytest.raises(MechanismError):
        Rod(1.0, 1.0).strain(1.0)


def test_mechanism_is_frozen_and_hashable():
    m = load_mechanism(PROTOTYPE)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.name = "x"  # type: ignore[misc]
    assert hash(m) == hash(load_mechanism(PROTOTYPE))
    assert m == load_mechanism(PROTOTYPE)
    assert len({m, load_mechanism(PROTOTYPE)}) == 1


# ---------------------------------------------------------------------------------------
# loader: good files and rules
# ---------------------------------------------------------------------------------------
BASE = """\
name = "test"

[rod]
length = 1.0
E = 68e9
radius = 1.5e-3

[platform]
attach = [[-0.2, -0.1], [0.2, -0.1], [0.0, 0.2]]

[[leg]]
actuation = "prismatic"
origin = [-0.9, -0.5]
angle = 0.0

[[leg]]
actuation = "prismatic"
origin = [0.9, -0.5]
angle = 120.0

[[leg]]
actuation = "prismatic"
origin = [0.0, 1.0]
angle = 240.0
"""

LEG = '\n[[leg]]\nactuation = "prismatic"\norigin = [0.5, 0.5]\nangle = 10.0\n'


def _write(tmp_path: Path, text: str, name: str = "mech.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _leg_block(i: int) -> tuple[int, int]:
    """Character span of the i-th (0-based) [[leg]] block in BASE."""
    starts = [k for k in range(len(BASE)) if BASE.startswith("[[leg]]", k)]
    ends = starts[1:] + [len(BASE)]
    return starts[i], ends[i]


def _without_leg(i: int) -> str:
    a, b = _leg_block(i)
    return BASE[:a] + BASE[b:]


def _sub(old: str, new: str, text: str = BASE, count: int = 1) -> str:
    assert old in text, old
    return text.replace(old, new, count)


def test_base_is_valid(tmp_path):
    m = load_mechanism(_write(tmp_path, BASE))
    assert m.name == "test"
    assert m.legs[1].angle == pytest.approx(math.radians(120))


def test_default_name_is_file_stem(tmp_path):
    m = load_mechanism(_write(tmp_path, _sub('name = "test"\n', ""), "my_robot.toml"))
    assert m.name == "my_robot"


def test_revolute_angle_optional_and_range_in_degrees(tmp_path):
    text = _sub('actuation = "prismatic"\norigin = [0.9, -0.5]\nangle = 120.0',
                'actuation = "revolute"\norigin = [0.9, -0.5]\nrange = [90.0, 270.0]')
    m = load_mechanism(_write(tmp_path, text))
    leg = m.legs[1]
    assert leg.actuation == "revolute" and leg.angle == 0.0
    assert leg.range == pytest.approx((math.pi / 2, 3 * math.pi / 2))
    assert m.kind == "mixed (P,R,P)"


def test_length_leg_ignores_rod_length(tmp_path):
    text = _sub('actuation = "prismatic"\norigin = [0.0, 1.0]\nangle = 240.0',
                'actuation = "length"\norigin = [0.0, 1.0]\nangle = 270.0\nrange = [0.2, 1.5]\nlength = 7.0')
    m = load_mechanism(_write(tmp_path, text))
    assert m.legs[2].rod.length is None
    assert m.legs[2].range == (0.2, 1.5)
    assert m.legs[0].rod.length == 1.0


def test_leg_overrides_and_EI_resolution(tmp_path):
    # a leg overriding radius gets EI recomputed; EI given directly works; consistent EI+E+radius ok
    EI0 = 68e9 * math.pi * 1.5e-3**4 / 4
    text = _sub('origin = [0.9, -0.5]\nangle = 120.0', 'origin = [0.9, -0.5]\nangle = 120.0\nradius = 2e-3\nlength = 0.8')
    text = _sub('origin = [0.0, 1.0]\nangle = 240.0', f'origin = [0.0, 1.0]\nangle = 240.0\nEI = {EI0!r}', text)
    m = load_mechanism(_write(tmp_path, text))
    assert m.legs[0].rod.EI == pytest.approx(EI0)
    assert m.legs[1].rod.EI == pytest.approx(68e9 * math.pi * 2e-3**4 / 4)
    assert m.legs[1].rod.length == 0.8 and m.legs[0].rod.length == 1.0
    assert m.legs[2].rod.EI == pytest.approx(EI0)
    # [rod] with EI only; a leg adds radius for strain checks without changing EI
    text = _sub("E = 68e9\nradius = 1.5e-3", "EI = 0.5")
    text = _sub("angle = 0.0", "angle = 0.0\nradius = 1e-3", text)
    m = load_mechanism(_write(tmp_path, text))
    assert [leg.rod.EI for leg in m.legs] == [0.5, 0.5, 0.5]
    assert m.legs[0].rod.radius == 1e-3 and m.legs[1].rod.radius is None


def test_load_and_limits(tmp_path):
    text = BASE + "\n[load]\nforce = [1.5, -2]\nmoment = 0.25\n\n[limits]\nmax_strain = 0.04\n"
    m = load_mechanism(_write(tmp_path, text))
    assert m.load == (1.5, -2.0, 0.25)
    assert m.max_strain == 0.04
    m = load_mechanism(_write(tmp_path, BASE + "\n[load]\nmoment = -1\n"))
    assert m.load == (0.0, 0.0, -1.0)


def test_mechanism_from_dict():
    data = tomllib.loads(BASE)
    m = mechanism_from_dict(data)
    assert m.source is None and m.name == "test"
    data2 = copy.deepcopy(data)
    data2["leg"][0]["origin"] = "abc"
    with pytest.raises(MechanismError, match=r"^<dict>: leg\[1\]\.origin: "):
        mechanism_from_dict(data2)
    with pytest.raises(MechanismError, match="x.toml"):
        mechanism_from_dict(data2, source="x.toml")
    with pytest.raises(MechanismError):
        mechanism_from_dict([1, 2, 3])  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------
# loader: bad files
# ---------------------------------------------------------------------------------------
BAD_CASES = [
    # id, file text, substrings the message must contain (besides the file name)
    ("malformed_value", _sub("angle = 0.0", "angle = 0.0.0"), ["malformed TOML", "line"]),
    ("malformed_bracket", _sub("origin = [-0.9, -0.5]", "origin = [-0.9, -0.5"), ["malformed TOML", "line"]),
    ("malformed_duplicate_key", _sub("angle = 0.0", "angle = 0.0\nangle = 1.0"), ["malformed TOML"]),
    ("bool_length", _sub("length = 1.0", "length = true"), ["rod.length", "number"]),
    ("bool_in_origin", _sub("origin = [-0.9, -0.5]", "origin = [true, -0.5]"), ["leg[1].origin"]),
    ("bool_angle", _sub("angle = 120.0", "angle = false"), ["leg[2].angle"]),
    ("nan_E", _sub("E = 68e9", "E = nan"), ["rod.E", "finite"]),
    ("inf_angle", _sub("angle = 120.0", "angle = inf"), ["leg[2].angle", "finite"]),
    ("nan_attach", _sub("[0.0, 0.2]]", "[0.0, nan]]"), ["platform.attach[3]"]),
    ("two_legs", _without_leg(2), ["leg", "three", "got 2"]),
    ("four_legs", BASE + LEG, ["leg", "three", "got 4"]),
    ("no_legs", _without_leg(2)[: _leg_block(0)[0]], ["leg", "missing"]),
    ("single_leg_table", _sub("[[leg]]", "[leg]", _without_leg(2)[: _leg_block(1)[0]]), ["leg", "[[leg]]"]),
    ("negative_EI", _sub("E = 68e9\nradius = 1.5e-3", "EI = -0.27"), ["rod.EI", "> 0"]),
    ("zero_length", _sub("length = 1.0", "length = 0.0"), ["rod.length", "> 0"]),
    ("zero_radius_in_leg", _sub("angle = 120.0", "angle = 120.0\nradius = 0"), ["leg[2].radius", "> 0"]),
    ("negative_E", _sub("E = 68e9", "E = -68e9"), ["rod.E"]),
    ("coincident_attach", _sub("[0.2, -0.1]", "[-0.2, -0.1]"), ["platform.attach", "coincide"]),
    ("collinear_attach", _sub("[0.0, 0.2]]", "[0.0, -0.1]]"), ["platform.attach", "collinear"]),
    ("two_attach_points", _sub(", [0.0, 0.2]]", "]"), ["platform.attach", "three"]),
    ("attach_not_point", _sub("[0.0, 0.2]]", "[0.0, 0.2, 0.3]]"), ["platform.attach[3]"]),
    ("unknown_leg_key", _sub("origin = [0.9, -0.5]", "orign = [0.9, -0.5]"), ["leg[2].orign", "did you mean 'origin'?"]),
    ("unknown_rod_key", _sub("length = 1.0", "lenght = 1.0"), ["rod.lenght", "did you mean 'length'?"]),
    ("unknown_top_key", _sub("[platform]", "[platfrom]"), ["platfrom", "did you mean 'platform'?"]),
    ("unknown_key_case", _sub("E = 68e9", "e = 68e9"), ["rod.e", "did you mean 'E'?"]),
    ("unknown_load_key", BASE + "\n[load]\nforces = [1, 2]\n", ["load.forces", "did you mean 'force'?"]),
    ("unknown_actuation", _sub('"prismatic"', '"prismatc"'), ["leg[1].actuation", "prismatc", "did you mean 'prismatic'?"]),
    ("actuation_not_string", _sub('actuation = "prismatic"', "actuation = 1"), ["leg[1].actuation", "string"]),
    ("range_lo_gt_hi", _sub("angle = 0.0", "angle = 0.0\nrange = [0.3, -0.1]"), ["leg[1].range", "lower bound"]),
    ("range_lo_eq_hi", _sub("angle = 0.0", "angle = 0.0\nrange = [0.1, 0.1]"), ["leg[1].range"]),
    ("range_three_values", _sub("angle = 0.0", "angle = 0.0\nrange = [0.1, 0.2, 0.3]"), ["leg[1].range"]),
    ("origin_string", _sub("origin = [0.9, -0.5]", 'origin = "abc"'), ["leg[2].origin", "'abc'"]),
    ("origin_string_number", _sub("origin = [0.9, -0.5]", 'origin = ["0.9", -0.5]'), ["leg[2].origin"]),
    ("missing_origin", _sub("origin = [0.0, 1.0]\n", ""), ["leg[3].origin", "missing"]),
    ("missing_angle_prismatic", _sub("angle = 0.0\n", ""), ["leg[1].angle", "missing"]),
    ("missing_actuation", _sub('actuation = "prismatic"\norigin = [0.9', "origin = [0.9"), ["leg[2].actuation", "missing"]),
    ("missing_platform", _sub("[platform]\nattach = [[-0.2, -0.1], [0.2, -0.1], [0.0, 0.2]]\n", ""), ["platform", "missing"]),
    ("missing_attach", _sub("attach = [[-0.2, -0.1], [0.2, -0.1], [0.0, 0.2]]\n", ""), ["platform.attach", "missing"]),
    ("missing_length", _sub("length = 1.0\n", ""), ["leg[1].length", "missing"]),
    ("missing_stiffness", _sub("E = 68e9\n", ""), ["leg[1].E", "missing"]),
    ("EI_disagrees", _sub("E = 68e9", "E = 68e9\nEI = 0.2704"), ["rod.EI", "disagrees"]),
    ("leg_EI_disagrees", _sub("angle = 120.0", "angle = 120.0\nEI = 5.0"), ["leg[2].EI", "disagrees"]),
    ("coincident_revolute_origins",
     _sub('actuation = "prismatic"\norigin = [0.0, 1.0]', 'actuation = "revolute"\norigin = [0.9, -0.5]',
          _sub('actuation = "prismatic"\norigin = [0.9, -0.5]', 'actuation = "revolute"\norigin = [0.9, -0.5]')),
     ["leg[3].origin", "coincides", "leg[2]"]),
    ("coincident_length_revolute_origins",
     _sub('actuation = "prismatic"\norigin = [0.0, 1.0]', 'actuation = "length"\norigin = [-0.9, -0.5]',
          _sub('actuation = "prismatic"\norigin = [-0.9, -0.5]', 'actuation = "revolute"\norigin = [-0.9, -0.5]')),
     ["leg[3].origin", "coincides"]),
    ("length_range_nonpositive",
     _sub('actuation = "prismatic"\norigin = [0.0, 1.0]\nangle = 240.0',
          'actuation = "length"\norigin = [0.0, 1.0]\nangle = 270.0\nrange = [0.0, 1.0]'),
     ["leg[3].range", "> 0"]),
    ("name_not_string", _sub('name = "test"', "name = 3"), ["name", "string"]),
    ("rod_not_table", _sub("[rod]\nlength = 1.0\nE = 68e9\nradius = 1.5e-3\n", "rod = 1.0\n"), ["rod", "table"]),
    ("load_force_one_value", BASE + "\n[load]\nforce = [1.0]\n", ["load.force"]),
    ("load_moment_string", BASE + '\n[load]\nmoment = "big"\n', ["load.moment"]),
    ("max_strain_negative", BASE + "\n[limits]\nmax_strain = -0.1\n", ["limits.max_strain", "> 0"]),
    ("max_strain_without_radius",
     _sub("E = 68e9\nradius = 1.5e-3", "EI = 0.3") + "\n[limits]\nmax_strain = 0.04\n",
     ["leg[1].radius", "max_strain"]),
]


@pytest.mark.parametrize("case_id, text, needles", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_file(tmp_path, case_id, text, needles):
    fname = f"bad_{case_id}.toml"
    path = _write(tmp_path, text, fname)
    with pytest.raises(MechanismError) as info:  # any other exception type fails the test
        load_mechanism(path)
    msg = str(info.value)
    assert type(info.value) is MechanismError
    assert fname in msg
    assert msg.startswith(str(path) + ": ")
    for needle in needles:
        assert needle in msg, f"{needle!r} not in {msg!r}"
    assert "\n" not in msg and "Traceback" not in msg


def test_bad_cases_are_many_and_distinct():
    assert len(BAD_CASES) >= 20
    assert len({c[1] for c in BAD_CASES}) == len(BAD_CASES)


def test_unreadable_files(tmp_path):
    with pytest.raises(MechanismError, match="nope.toml: file not found"):
        load_mechanism(tmp_path / "nope.toml")
    with pytest.raises(MechanismError, match="directory"):
        load_mechanism(tmp_path)
    p = tmp_path / "binary.toml"
    p.write_bytes(b"name = \"\xff\xfe\"\n")
    with pytest.raises(MechanismError, match="binary.toml: not a UTF-8"):
        load_mechanism(p)
    p = _write(tmp_path, "", "empty.toml")
    with pytest.raises(MechanismError, match=r"empty.toml: platform: missing"):
        load_mechanism(p)


def _junk_values():
    return [None, True, False, "x", "", -1, 0, 0.0, -0.5, 1e308, float("nan"), float("inf"), [], [1], [1, 2],
            [1, 2, 3], ["a", "b"], [[1, 2]], {}, {"a": 1}, [True, 1.0], object()]


def _leaf_paths(obj, prefix=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield prefix + (k,)
            yield from _leaf_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield prefix + (i,)
            yield from _leaf_paths(v, prefix + (i,))


def test_fuzzed_dicts_only_raise_mechanism_error():
    """Replacing or deleting any entry of a valid description with junk yields either a
    Mechanism or a MechanismError, never another exception."""
    base = tomllib.loads(BASE + "\n[load]\nforce = [1.0, 2.0]\nmoment = 0.1\n[limits]\nmax_strain = 0.05\n")
    paths = list(_leaf_paths(base))
    rnd = random.Random(12345)
    n_err = n_ok = 0
    for _ in range(600):
        data = copy.deepcopy(base)
        path = rnd.choice(paths)
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        if rnd.random() < 0.2:
            del parent[path[-1]]
        else:
            parent[path[-1]] = rnd.choice(_junk_values())
        try:
            m = mechanism_from_dict(data, source="fuzz.toml")
            assert isinstance(m, Mechanism)
            n_ok += 1
        except MechanismError as exc:
            assert str(exc).startswith("fuzz.toml: ")
            assert "internal" not in str(exc) and "invalid mechanism description" not in str(exc), str(exc)
            n_err += 1
    assert n_err > 400  # most mutations are errors; the loop really exercises the checks


# ---------------------------------------------------------------------------------------
# builders
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("actuation", ACTUATIONS)
def test_builder_C3_symmetry(actuation):
    m = symmetric_mechanism(actuation)
    rot = 2 * math.pi / 3
    for i in range(3):
        j = (i + 1) % 3
        li, lj = m.legs[i], m.legs[j]
        assert np.allclose(_rot(rot, li.origin), lj.origin, atol=1e-14)
        assert np.allclose(_rot(rot, m.platform.attach[i]), m.platform.attach[j], atol=1e-14)
        if actuation != "revolute":  # a revolute leg's file angle is unused (0 for all legs)
            assert np.allclose(_rot(rot, li.direction), lj.direction, atol=1e-14)
        assert li.rod == lj.rod and li.actuation == lj.actuation == actuation
    # the platform frame at the symmetric pose also maps to itself: B_i rotated = B_{i+1}
    B = m.platform.world([0.0, 0.0, 0.3])
    assert np.allclose(_rot(rot, B[0]), B[1], atol=1e-14)


def test_builder_geometry():
    p = symmetric_mechanism("prismatic", base_radius=2.0, platform_radius=0.5, length=1.5, EI=3.0, name="x")
    assert p.name == "x" and p.kind == "3-PFR"
    assert p.legs[0].origin == pytest.approx((-math.sqrt(3), -1.0))
    assert p.legs[2].origin == (0.0, 2.0)
    assert [math.degrees(leg.angle) for leg in p.legs] == pytest.approx([0.0, 120.0, 240.0])
    # leg i's guide runs along the base edge towards V_{i+1}
    for i in range(3):
        e = np.subtract(p.legs[(i + 1) % 3].origin, p.legs[i].origin)
        assert np.allclose(e / np.linalg.norm(e), p.legs[i].direction)
    assert p.platform.attach[2] == (0.0, 0.5)
    assert all(leg.rod == Rod(1.5, 3.0) for leg in p.legs)
    ln = symmetric_mechanism("length")
    assert ln.kind == "3-PFR(length)" and all(leg.rod.length is None for leg in ln.legs)
    for leg in ln.legs:  # guide exits point at the base centroid
        to_c = -np.asarray(leg.origin) / np.linalg.norm(leg.origin)
        assert np.allclose(leg.direction, to_c)
    assert ln.length_scale == pytest.approx(1.0)
    rv = symmetric_mechanism("revolute")
    assert rv.kind == "3-RFR" and all(leg.angle == 0.0 for leg in rv.legs)
    with pytest.raises(MechanismError):
        symmetric_mechanism("spring")  # type: ignore[arg-type]
    with pytest.raises(MechanismError):
        symmetric_mechanism("prismatic", EI=-1.0)


# ---------------------------------------------------------------------------------------
# example files
# ---------------------------------------------------------------------------------------
EXAMPLE_FILES = ["prototype_3pfr", "unit_3pfr", "unit_3rfr", "unit_3pfr_length", "mixed_legs"]


@pytest.mark.parametrize("stem", EXAMPLE_FILES)
def test_example_files_load(stem):
    m = load_mechanism(EXAMPLES / f"{stem}.toml")
    assert isinstance(m, Mechanism) and len(m.legs) == 3
    assert m.summary().startswith(m.name)


@pytest.mark.parametrize(
    "stem, actuation", [("unit_3pfr", "prismatic"), ("unit_3rfr", "revolute"), ("unit_3pfr_length", "length")]
)
def test_unit_examples_match_builder(stem, actuation):
    m = load_mechanism(EXAMPLES / f"{stem}.toml")
    b = symmetric_mechanism(actuation)
    assert m.kind == b.kind
    assert np.allclose(m.platform.b, b.platform.b, atol=1e-15)
    for lm, lb in zip(m.legs, b.legs):
        assert lm.actuation == lb.actuation
        assert np.allclose(lm.origin, lb.origin, atol=1e-15)
        assert _same_angle(lm.angle, lb.angle)
        assert lm.rod == lb.rod


def test_mixed_example():
    m = load_mechanism(EXAMPLES / "mixed_legs.toml")
    assert m.kind == "mixed (P,R,L)"
    assert m.actuations == ("prismatic", "revolute", "length")
    assert m.load != (0.0, 0.0, 0.0)
    assert m.max_strain is not None
    assert not m.is_symmetric_rods
    assert m.legs[1].rod.EI == pytest.approx(68e9 * math.pi * 1.8e-3**4 / 4)
    assert m.legs[2].rod.length is None
    assert m.legs[1].range == pytest.approx((math.radians(60), math.radians(240)))


# ---------------------------------------------------------------------------------------
# plotting
# ---------------------------------------------------------------------------------------
def _fake_rods(m: Mechanism, pose, inputs):
    B = m.platform.world(pose)
    rods = []
    t = np.linspace(0.0, 1.0, 40)[:, None]
    for i, leg in enumerate(m.legs):
        A, a, _ = leg.clamp(inputs[i])
        C = A + 0.4 * np.linalg.norm(B[i] - A) * np.array([math.cos(a), math.sin(a)])
        rods.append((1 - t) ** 2 * A + 2 * t * (1 - t) * C + t**2 * B[i])
    return rods


@pytest.mark.parametrize("stem", EXAMPLE_FILES)
def test_plot_mechanism_png(tmp_path, stem):
    import matplotlib

    matplotlib.use("Agg")
    from flexkin.plot.mechanism import plot_mechanism, plot_mechanism_file

    m = load_mechanism(EXAMPLES / f"{stem}.toml")
    out = plot_mechanism_file(m, tmp_path / f"{stem}.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000
    pose = np.array([0.01, -0.02, 0.4])
    inputs = [0.3 if leg.actuation == "length" else (math.pi / 2 if leg.actuation == "revolute" else 0.05)
              for leg in m.legs]
    rods = _fake_rods(m, pose, inputs)
    ax = plot_mechanism(m, pose=pose, rods=rods, inputs=inputs, title="t")
    assert ax.get_xlabel() == "X [m]" and ax.get_ylabel() == "Y [m]" and ax.get_title() == "t"
    assert ax.get_aspect() == 1.0
    texts = sorted(t.get_text() for t in ax.texts)
    assert texts == ["1", "2", "3"]
    # the drawing covers the rods and the platform
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    pts = np.concatenate(rods)
    assert x0 <= pts[:, 0].min() and pts[:, 0].max() <= x1 and y0 <= pts[:, 1].min() and pts[:, 1].max() <= y1
    png = tmp_path / f"{stem}_rods.png"
    ax.figure.savefig(png, dpi=150)
    assert png.stat().st_size > 10_000


def test_plot_into_given_axes_and_bad_rods():
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from flexkin.plot.mechanism import plot_mechanism

    fig = Figure()
    ax = fig.add_subplot()
    m = symmetric_mechanism("revolute")
    assert plot_mechanism(m, ax=ax) is ax
    with pytest.raises(ValueError):
        plot_mechanism(m, rods=[np.zeros((3, 2))] * 2)
    with pytest.raises(ValueError):
        plot_mechanism(m, rods=[np.zeros((3, 3))] * 3)


# ---------------------------------------------------------------------------------------
# plausibility warnings (issue 18, defect 5) and the Cosserat keys (issue 16)
# ---------------------------------------------------------------------------------------
REVOLUTE_BASE = """\
name = "spring-steel 3-RFR"

[rod]
length = 0.6
E = 200e9
radius = 1.0e-3

[platform]
attach = [[-0.05, -0.03], [0.05, -0.03], [0.0, 0.06]]

[[leg]]
actuation = "revolute"
origin = [-0.433, -0.25]
range = [-60.0, 120.0]

[[leg]]
actuation = "revolute"
origin = [0.433, -0.25]
range = [60.0, 240.0]

[[leg]]
actuation = "revolute"
origin = [0.0, 0.5]
range = [180.0, 360.0]
"""


def _warnings_of(path) -> list[str]:
    import warnings

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        load_mechanism(path)
    return [str(w.message) for w in rec if issubclass(w.category, FlexkinWarning)]


def test_plausible_files_load_without_warnings(tmp_path):
    assert _warnings_of(_write(tmp_path, REVOLUTE_BASE)) == []
    for stem in EXAMPLE_FILES:
        assert _warnings_of(EXAMPLES / f"{stem}.toml") == [], stem


@pytest.mark.parametrize("old, new, needles", [
    ("radius = 1.0e-3", "radius = 1.0", ["rod.radius", "radius = 1 m", "rod length 0.6 m", "slender"]),
    ("E = 200e9", "E = 200", ["rod.E", "E = 200 Pa", "far below", "GPa"]),
    ("range = [-60.0, 120.0]", "range = [-1.05, 2.09]", ["leg[1].range", "[-1.05, 2.09]", "radians", "degrees",
                                                         "[-60.16, 119.7]"]),
    ('origin = [0.433, -0.25]\n', 'origin = [0.433, -0.25]\nangle = 30.0\n', ["leg[2].angle", "no effect",
                                                                              "revolute"]),
])
def test_implausible_values_warn_naming_key_value_and_expectation(tmp_path, old, new, needles):
    path = _write(tmp_path, _sub(old, new, REVOLUTE_BASE))
    msgs = _warnings_of(path)
    assert len(msgs) == 1, msgs
    assert msgs[0].startswith(f"{path}: ")
    for needle in needles:
        assert needle in msgs[0], (needle, msgs[0])


def test_per_leg_radius_warns_with_the_leg_key(tmp_path):
    text = _sub('origin = [0.0, 0.5]\n', 'origin = [0.0, 0.5]\nradius = 0.05\n', REVOLUTE_BASE)
    msgs = _warnings_of(_write(tmp_path, text))
    assert len(msgs) == 1 and "leg[3].radius" in msgs[0] and "0.05 m" in msgs[0]


def test_impossible_values_stay_errors(tmp_path):
    with pytest.raises(MechanismError, match=r"rod\.radius"):
        load_mechanism(_write(tmp_path, _sub("radius = 1.0e-3", "radius = -1.0", REVOLUTE_BASE)))


def test_revolute_inputs_in_radians_are_recognised():
    from flexkin.mechanism.plausibility import revolute_inputs_look_like_radians

    m = load_mechanism(EXAMPLES / "unit_3rfr.toml")  # ranges [-60, 120], [60, 240], [180, 360]
    note = revolute_inputs_look_like_radians(m, [1.58, 2.62, 4.71])
    assert note is not None and "--inputs" in note and "radians" in note and "90.53" in note
    assert revolute_inputs_look_like_radians(m, [90.0, 150.0, 270.0]) is None   # degrees, in range
    assert revolute_inputs_look_like_radians(m, [0.0, 0.0, 0.0]) is None
    proto = load_mechanism(PROTOTYPE)  # no revolute leg
    assert revolute_inputs_look_like_radians(proto, [0.025, 0.025, 0.025]) is None


COSSERAT_KEYS = """
[rod]
length = 1.0
E = 200e9
radius = 1.0e-3
poisson = 0.3
density = 7850
"""


def test_cosserat_keys_validated_and_resolved_per_leg(tmp_path):
    from flexkin.cosserat.params import cosserat_setup, leg_materials

    text = _sub("[rod]\nlength = 1.0\nE = 68e9\nradius = 1.5e-3\n", COSSERAT_KEYS.lstrip("\n"))
    text = _sub("angle = 120.0", "angle = 120.0\nG = 7e10\nshear_coefficient = 0.8\ndensity = 6450", text)
    text += "\n[environment]\ngravity = [0.0, -9.81]\n"
    m = load_mechanism(_write(tmp_path, text))
    mats = leg_materials(m)
    assert mats[0] == {"poisson": 0.3, "density": 7850.0}
    # leg 2 gives G: the inherited poisson is dropped; its own density and shear coefficient win
    assert mats[1] == {"G": 7e10, "density": 6450.0, "shear_coefficient": 0.8}
    assert m.gravity == (0.0, -9.81)
    assert m.legs[1].rod.G == 7e10 and m.legs[0].rod.poisson == 0.3
    params, g = cosserat_setup(m)
    A = math.pi * 1e-6
    assert params[0].EA == pytest.approx(200e9 * A)
    assert params[0].GA == pytest.approx(200e9 / 2.6 * A)
    assert params[0].mass_per_length == pytest.approx(7850 * A)
    assert params[1].GA == pytest.approx(7e10 * A) and params[1].shear_coefficient == 0.8
    assert g == (0.0, -9.81)
    assert cosserat_setup(m, gravity=(9.81, 0.0))[1] == (9.81, 0.0)


@pytest.mark.parametrize("extra, needles", [
    ("poisson = 0.7", ["rod.poisson", "(-1, 0.5]"]),
    ("density = -1.0", ["rod.density", ">= 0"]),
    ("G = 0.0", ["rod.G", "> 0"]),
    ("poisson = 0.3\nG = 1e9", ["rod.G", "disagrees", "E / (2 (1 + poisson))"]),
    ("shear_coefficient = -0.5", ["rod.shear_coefficient"]),
    ("densty = 7850", ["rod.densty", "did you mean 'density'?"]),
])
def test_bad_cosserat_keys_are_one_line_errors(tmp_path, extra, needles):
    path = _write(tmp_path, _sub("radius = 1.5e-3", f"radius = 1.5e-3\n{extra}"))
    with pytest.raises(MechanismError) as info:
        load_mechanism(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: ") and "\n" not in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_environment_gravity_checked(tmp_path):
    with pytest.raises(MechanismError, match=r"environment\.gravity"):
        load_mechanism(_write(tmp_path, BASE + "\n[environment]\ngravity = [0.0]\n"))
    with pytest.raises(MechanismError, match=r"environment\.wind.*allowed keys here: gravity"):
        load_mechanism(_write(tmp_path, BASE + "\n[environment]\nwind = [0.0, 1.0]\n"))


def test_every_file_key_is_documented_in_the_repository():
    import re

    from flexkin.mechanism import loader

    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs" / "mechanism_file.md").read_text(encoding="utf-8")
    keys = set(loader._TOP_KEYS + loader._ROD_KEYS + loader.MATERIAL_KEYS + loader._LEG_KEYS + loader._LOAD_KEYS
               + loader._LIMITS_KEYS + loader._ENVIRONMENT_KEYS + loader._PLATFORM_KEYS)
    for key in sorted(keys):
        assert re.search(rf"`(\[\[?)?{re.escape(key)}(\]\]?)?`", doc), key
    for word in ("unit", "default", "override", "range", "limits", "load", "tip_angle", "joint", "dimensionless"):
        assert word in doc, word
    # the README points to the file that documents the format, and the file is in the repository
    readme = (root / "README.md").read_text(encoding="utf-8")
    assert "docs/mechanism_file.md" in readme
    # the documented example parses (with its one [[leg]] repeated on the prototype's guides)
    block = doc.split("```toml\n", 1)[1].split("```", 1)[0]
    data = tomllib.loads(block)
    leg = data["leg"][0]
    data["leg"] = [leg, dict(leg, origin=[0.784, -0.458], angle=120.0), dict(leg, origin=[0.005, 0.908], angle=240.0)]
    m = mechanism_from_dict(data, source="<doc>")
    assert m.name == "3-PFR prototype" and m.legs[0].rod.radius == 1.5e-3
