"""Property-based tests (hypothesis) on random valid mechanisms.

Mechanisms are the paper's C3-symmetric kind (:func:`flexkin.mechanism.symmetric_mechanism`'s
conventions) with every leg's actuation drawn independently (3-P̲FR, 3-R̲FR, 3-PF̲R or mixed)
and randomly perturbed: base vertices, guide angles, platform attach points, per-leg rod
lengths, per-leg EI (a common EI drawn over six orders of magnitude, 1e-3 .. 1e3 N m^2, times a
per-leg factor 0.5 .. 2) and an overall length scale (0.1 .. 10).  Poses are near the centre,
around a generic reference pose (so that the simplest example is not the exactly symmetric,
singular configuration of the unperturbed mechanism, see ``test_fuzz``'s known bugs).

Properties
----------
(a) every IK solution passes the independent ODE verification of ``tests/ik_oracle.py``
    (tips on the platform points, zero tip moments, platform equilibrium, SPEC §2 clamps,
    d-modes = inflection counts), as in ``tests/test_ik.py``;
(b) scale invariance: lengths x s and EI x c with the load scaled as forces x c/s^2 and
    moments x c/s give the same solutions with inputs (m) x s, revolute inputs unchanged,
    tip forces x c/s^2, base moments and energies x c/s, the same d-modes and stability;
(c) IK -> FK round trip: FK at the inputs of one IK solution finds its pose again, and
    every FK solution passes the same ODE verification;
(d) the loader rejects random bad files cleanly (MechanismError, one line naming the file);
(e) determinism: the same IK twice gives bitwise-identical solution lists (same order).

Example counts: small in the default run (FK costs seconds per call); the ``@pytest.mark.slow``
twins run >= 200 examples each (``settings(max_examples=200, deadline=None)``).  Hypothesis runs
derandomized and without its example database, so every run draws the same examples.
"""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import event as _event
from hypothesis import note as _note
from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

import flexkin
from flexkin import MechanismError, load_mechanism
from flexkin.mechanism import Leg, Mechanism, Platform, Rod, mechanism_from_dict
from flexkin.mechanism.builders import SYMMETRIC_VERTEX_ANGLES_DEG

sys.path.insert(0, os.path.dirname(__file__))
import ik_oracle as O  # noqa: E402

try:
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
MAX_MODE = 2

COMMON = dict(deadline=None, database=None, derandomize=True, print_blob=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                     HealthCheck.function_scoped_fixture])
FAST = settings(max_examples=8, **COMMON)
FAST_FK = settings(max_examples=2, **COMMON)
FAST_LOADER = settings(max_examples=300, **COMMON)  # the loader is cheap: many examples by default
SLOW = settings(max_examples=200, **COMMON)

_COUNTS: dict[str, int] = {}


def note(msg: str) -> None:
    """hypothesis.note inside a hypothesis test, print otherwise."""
    try:
        _note(msg)
    except InvalidArgument:
        print(msg)


def event(msg: str) -> None:
    try:
        _event(msg)
    except InvalidArgument:
        pass


def count(key: str, n: int = 1) -> None:
    _COUNTS[key] = _COUNTS.get(key, 0) + n
    REPORT[f"properties: {key}"] = _COUNTS[key]


# ======================================================================================
# strategies
# ======================================================================================
KIND = {"P": "prismatic", "R": "revolute", "L": "length"}
PRISMATIC_ANGLES = (0.0, 120.0, 240.0)


def _f(lo: float, hi: float):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def mechanisms(draw, kinds=("PPP", "RRR", "LLL", "mixed")):
    """A random valid mechanism near the paper's symmetric arrangement (see the module docstring)."""
    kind = draw(st.sampled_from(kinds))
    if kind == "mixed":
        acts = tuple(KIND[draw(st.sampled_from("PRL"))] for _ in range(3))
    else:
        acts = (KIND[kind[0]],) * 3
    scale = 10.0 ** draw(_f(-1.0, 1.0))
    EI0 = 10.0 ** draw(_f(-3.0, 3.0))
    rp = draw(_f(0.18, 0.32))
    legs, attach = [], []
    for i, act in enumerate(acts):
        a = math.radians(SYMMETRIC_VERTEX_ANGLES_DEG[i] + draw(_f(-6.0, 6.0)))
        R = 1.0 + draw(_f(-0.08, 0.08))
        origin = (scale * R * math.cos(a), scale * R * math.sin(a))
        if act == "prismatic":
            angle = math.radians(PRISMATIC_ANGLES[i] + draw(_f(-8.0, 8.0)))
        elif act == "revolute":
            angle = 0.0
        else:
            angle = math.radians(SYMMETRIC_VERTEX_ANGLES_DEG[i] + 180.0 + draw(_f(-8.0, 8.0)))
        length = None if act == "length" else scale * draw(_f(0.95, 1.25))
        EI = EI0 * draw(_f(0.5, 2.0))
        legs.append(Leg(actuation=act, origin=origin, angle=angle, rod=Rod(length=length, EI=EI)))
        b = math.radians(SYMMETRIC_VERTEX_ANGLES_DEG[i] + draw(_f(-8.0, 8.0)))
        attach.append((scale * (rp * math.cos(b) + draw(_f(-0.03, 0.03))),
                       scale * (rp * math.sin(b) + draw(_f(-0.03, 0.03)))))
    mech = Mechanism(name=f"random {''.join(a[0].upper() for a in acts)}", legs=tuple(legs),
                     platform=Platform(attach=tuple(attach)))
    note(f"mechanism: {describe(mech)}")
    return mech


def describe(m: Mechanism) -> str:
    """A reproducer: the mechanism as Python constructor arguments (full precision)."""
    legs = ", ".join(f"Leg({leg.actuation!r}, {leg.origin!r}, {leg.angle!r}, Rod({leg.rod.length!r}, {leg.rod.EI!r}))"
                     for leg in m.legs)
    return f"Mechanism({m.name!r}, ({legs}), Platform({m.platform.attach!r}))"


@st.composite
def poses(draw, mech: Mechanism):
    """A pose near the centre of the base: a generic reference pose plus a small offset."""
    s = mech.length_scale
    x = s * (0.03 + draw(_f(-0.05, 0.05)))
    y = s * (-0.02 + draw(_f(-0.05, 0.05)))
    th = math.radians(12.0 + draw(_f(-20.0, 20.0)))
    note(f"pose: ({x!r}, {y!r}, {th!r})")
    return (x, y, th)


@st.composite
def loads(draw, mech: Mechanism):
    """Zero (often) or a load of up to 0.3 EI/L^2 (forces) and 0.03 EI/L (moment)."""
    if draw(st.booleans()):
        return (0.0, 0.0, 0.0)
    F = mech.EI_scale / mech.length_scale**2
    w = (F * draw(_f(-0.3, 0.3)), F * draw(_f(-0.3, 0.3)), F * mech.length_scale * draw(_f(-0.03, 0.03)))
    note(f"load: {w!r}")
    return w


@st.composite
def problems(draw, kinds=("PPP", "RRR", "LLL", "mixed")):
    mech = draw(mechanisms(kinds))
    return mech, draw(poses(mech)), draw(loads(mech))


# ======================================================================================
# (a) every IK solution passes the independent ODE verification
# ======================================================================================
def dense_mode(mech, sol, i: int, n_eval: int = 200_001) -> int:
    """d-mode of rod ``i`` of ``sol`` from a dense re-integration, counting sign changes of the
    moment on [0, L) INCLUDING the first interval (as ik_oracle.count_inflections does since
    issue 27; it used to drop the clamp sample and so missed an inflection closer to the clamp
    than L/2000, seen on random mechanisms with s/L = 4.5e-4)."""
    g = O.Geom.of(mech)
    r = sol.rods[i]
    A, al, L = g.clamp(i, np.asarray(sol.inputs[i], float))
    ode = O.integrate_rod(r.tip_force, r.base_moment, np.asarray(A, float), float(al), float(L), g.EI[i],
                          n_eval=n_eval)
    ms = ode.ms[:-1]  # the pinned tip's zero is not a sign change
    scale = float(np.max(np.abs(ode.ms)))
    sg = np.sign(ms[np.abs(ms) > 1e-9 * scale])
    return 1 + int(np.count_nonzero(sg[1:] != sg[:-1]))


def tight_rod_errors(mech, sol, pose) -> tuple[float, float]:
    """Max tip error (m) and max |m(L)| L/EI over the rods of ``sol``, each rod integrated alone
    with rtol = atol = 2.5e-14 (the batch verification's error norm is shared by all rods, and
    forward integration amplifies round-off like 1/k'^2 near |k| = 1)."""
    g = O.Geom.of(mech)
    ps = np.asarray(sol.pose if pose is None else pose, float)
    B = g.platform_points(ps)
    tip, mom = 0.0, 0.0
    for i, r in enumerate(sol.rods):
        A, al, L = g.clamp(i, np.asarray(sol.inputs[i], float))
        ode = O.integrate_rod(r.tip_force, r.base_moment, np.asarray(A, float), float(al), float(L), g.EI[i],
                              n_eval=2, rtol=2.5e-14, atol=2.5e-14)
        tip = max(tip, float(np.hypot(*(ode.tip - B[i]))))
        mom = max(mom, abs(ode.m_tip) * float(L) / g.EI[i])
    return tip, mom


def verification_problems(mech, sols, load, pose=None) -> list[str]:
    """tests/test_ik.py's acceptance criteria, for every solution."""
    L_ref = O.Geom.of(mech).L_ref
    checks = O.verify_many(mech, sols, load, pose)
    bad = []
    for s, v in zip(sols, checks):
        p = []
        kp = min(math.sqrt(max(1.0 - r.k * r.k, 1e-300)) for r in s.rods)
        tip_tol, mom_tol = 1e-8 * L_ref, 1e-6 * max(1.0, (1e-4 / kp) ** 2)
        tip_err, mom_err = v["tip_error"], v["tip_moment"]
        if tip_err > tip_tol or mom_err > mom_tol:  # confirm with a tighter single-rod integration
            tip_err, mom_err = tight_rod_errors(mech, s, pose)
            count("(a) tip checks repeated with a tighter single-rod integration")
        if tip_err > tip_tol:
            p.append(f"tip error {tip_err:.2e} m (k' = {kp:.1e})")
        if mom_err > mom_tol:
            p.append(f"tip moment {mom_err:.2e} EI/L (k' = {kp:.1e})")
        if v["eq_force"] > 1e-8 or v["eq_moment"] > 1e-8:
            p.append(f"equilibrium {v['eq_force']:.2e}/{v['eq_moment']:.2e}")
        if v["clamp_error"] > 1e-12 * max(L_ref, 1.0):
            p.append(f"clamp differs from SPEC §2 by {v['clamp_error']:.2e}")
        for i, (q_rep, q_ode, amb) in enumerate(zip(s.modes, v["modes"], v["mode_ambiguous"])):
            if q_rep != q_ode and not amb:
                q_dense = dense_mode(mech, s, i)
                count("(a) d-modes confirmed by dense re-integration (oracle sampling too coarse)")
                if q_dense == q_rep:
                    continue
                p.append(f"mode {s.modes} reported, inflections {v['modes']} (dense count {q_dense} for rod {i + 1})")
                break
            if abs(q_rep - q_ode) > 2:
                p.append(f"mode {s.modes} reported, inflections {v['modes']}")
                break
        if any(q > MAX_MODE for q in s.modes):
            p.append(f"mode {s.modes} above max_mode")
        if pose is not None and not np.allclose(s.pose, pose, rtol=0, atol=1e-14 * max(1.0, L_ref)):
            p.append("pose differs from the requested pose")
        if p:
            bad.append(f"{s.mode_label} inputs {tuple(round(u, 9) for u in s.inputs)}: {p}")
    return bad


def check_ik_verified(problem):
    mech, pose, load = problem
    res = flexkin.ik(mech, pose, load=load, max_mode=MAX_MODE)
    count("(a) IK examples")
    count("(a) IK solutions verified", len(res))
    event(f"{len(res) > 0 and 'solutions' or 'no solution'}")
    assert isinstance(res.message, str)
    bad = verification_problems(mech, res.solutions, load, pose)
    assert not bad, f"{len(bad)} of {len(res)} solutions fail the ODE verification: {bad[:5]}"


@FAST
@given(problems())
def test_ik_solutions_verified(problem):
    check_ik_verified(problem)


@pytest.mark.slow
@SLOW
@given(problems())
def test_ik_solutions_verified_slow(problem):
    check_ik_verified(problem)


def test_ik_verified_near_loop_rod():
    """Example found by the slow run: a 122 solution with a near-loop rod (k' = 1.3e-6): the batch
    verification's tip error (1.5e-8 m) exceeds 1e-8 L, a single tight integration gives 4e-10."""
    m = Mechanism("random PPP", (
        Leg("prismatic", (-0.8660254037844386, -0.5000000000000001), 0.0, Rod(1.25, 0.8125)),
        Leg("prismatic", (0.7950450901466494, -0.4967993102186297), 2.1467549799530254, Rod(1.125, 1.875)),
        Leg("prismatic", (6.123233995736766e-17, 1.0), 4.1887902047863905, Rod(1.0, 1.0))),
        Platform(((-0.27063293868263705, -0.14062500000000003), (0.270632938682637, -0.15625000000000014),
                  (1.9135106236677395e-17, 0.3125))))
    check_ik_verified((m, (0.03375, -0.0225, 0.20943951023931956), (0.0, 0.0, 0.0)))


def test_ik_verified_inflection_near_the_clamp():
    """Example found by the slow run: a 212 solution whose rod 1 has an inflection at s/L = 4.5e-4
    (before the oracle's first interior sample, see :func:`dense_mode`); flexkin's d-mode 2 is
    right, and so is the oracle's count since it compares the clamp's moment with the first
    sample (issue 27)."""
    m = Mechanism("random PPP", (
        Leg("prismatic", (-0.8571673007021123, -0.5150380749100542), 0.0, Rod(1.25, 0.5)),
        Leg("prismatic", (0.7950450901466494, -0.4967993102186297), 2.0943951023931953, Rod(1.125, 1.5)),
        Leg("prismatic", (6.123233995736766e-17, 1.0), 4.1887902047863905, Rod(1.0, 1.0))),
        Platform(((-0.24356964481437335, -0.12500000000000003), (0.2435696448143733, -0.1406250000000001),
                  (1.7221595613009655e-17, 0.28125))))
    pose = (0.03375, -0.0225, 0.24434609527920614)
    check_ik_verified((m, pose, (0.0, 0.0, 0.0)))
    s = next(s for s in flexkin.ik(m, pose).solutions
             if s.mode_label == "212" and abs(s.inputs[0] + 0.504268302) < 1e-6)
    assert O.verify_solution(m, s, (0, 0, 0), pose)["modes"][0] == 2  # the oracle's count
    assert dense_mode(m, s, 0) == 2 == s.modes[0]


# ======================================================================================
# (b) scale invariance
# ======================================================================================
def scaled(mech: Mechanism, s: float, c: float) -> Mechanism:
    """Lengths x s, EI x c (angles unchanged)."""
    legs = tuple(Leg(actuation=leg.actuation, origin=(leg.origin[0] * s, leg.origin[1] * s), angle=leg.angle,
                     rod=Rod(length=None if leg.rod.length is None else leg.rod.length * s, EI=leg.rod.EI * c))
                 for leg in mech.legs)
    attach = tuple((x * s, y * s) for x, y in mech.platform.attach)
    return Mechanism(name=mech.name + " scaled", legs=legs, platform=Platform(attach=attach),
                     load=(mech.load[0] * c / s**2, mech.load[1] * c / s**2, mech.load[2] * c / s))


def _signature(mech, sol, s: float, c: float):
    """Dimensionless description of a solution of a mechanism scaled by (s, c)."""
    u = [ui if leg.actuation == "revolute" else ui / s for ui, leg in zip(sol.inputs, mech.legs)]
    f = [v * s * s / c for r in sol.rods for v in r.tip_force]
    m0 = [r.base_moment * s / c for r in sol.rods]
    return np.array(u), np.array(f), np.array(m0), sol.energy * s / c


def check_scale_invariance(problem, s: float, c: float):
    mech, pose, load = problem
    note(f"s = {s!r}, c = {c!r}")
    ref = flexkin.ik(mech, pose, load=load, max_mode=MAX_MODE)
    m2 = scaled(mech, s, c)
    pose2 = (pose[0] * s, pose[1] * s, pose[2])
    load2 = (load[0] * c / s**2, load[1] * c / s**2, load[2] * c / s)
    res = flexkin.ik(m2, pose2, load=load2, max_mode=MAX_MODE)
    count("(b) scale-invariance examples")
    count("(b) solutions compared", len(ref))
    L, F = mech.length_scale, mech.EI_scale / mech.length_scale**2
    A = [_signature(mech, x, 1.0, 1.0) for x in ref.solutions]
    B = [_signature(m2, x, s, c) for x in res.solutions]
    unmatched_b = list(range(len(B)))
    missing = []
    for i, (sa, a) in enumerate(zip(ref.solutions, A)):
        hit = None
        for j in unmatched_b:
            sb, b = res.solutions[j], B[j]
            du = np.abs(a[0] - b[0]) / np.array([1.0 if leg.actuation == "revolute" else L for leg in mech.legs])
            if (sa.modes == sb.modes and np.max(du) < 1e-7 and np.max(np.abs(a[1] - b[1])) < 1e-6 * max(F, np.max(np.abs(a[1])))
                    and np.max(np.abs(a[2] - b[2])) < 1e-6 * max(F * L, np.max(np.abs(a[2])))
                    and abs(a[3] - b[3]) <= 1e-6 * max(F * L, abs(a[3]))):
                hit = j
                break
        if hit is None:
            missing.append(f"{sa.mode_label} inputs {tuple(round(u, 9) for u in sa.inputs)} "
                           f"k {tuple(round(r.k, 9) for r in sa.rods)}")
            continue
        unmatched_b.remove(hit)
        sb = res.solutions[hit]
        if sa.stability_margin is not None and abs(sa.stability_margin) > 1e-6:
            assert sa.stable == sb.stable, (sa.mode_label, sa.stability_margin, sb.stability_margin)
    extra = [f"{res.solutions[j].mode_label} k {tuple(round(r.k, 9) for r in res.solutions[j].rods)}"
             for j in unmatched_b]
    assert not missing and not extra, (f"{len(ref)} vs {len(res)} solutions; not found after scaling: {missing[:5]}; "
                                       f"new after scaling: {extra[:5]}")


@FAST
@given(problems(), _f(-3.0, 3.0), _f(-3.0, 3.0))
def test_scale_invariance(problem, log_s, log_c):
    check_scale_invariance(problem, 10.0**log_s, 10.0**log_c)


@pytest.mark.slow
@SLOW
@given(problems(), _f(-3.0, 3.0), _f(-3.0, 3.0))
def test_scale_invariance_slow(problem, log_s, log_c):
    check_scale_invariance(problem, 10.0**log_s, 10.0**log_c)


def test_scale_invariance_exact_powers_of_two():
    """With s and c powers of two every scaled quantity is exact: the inputs must agree to
    round-off (a deterministic example, independent of hypothesis)."""
    from flexkin.mechanism import symmetric_mechanism

    m = symmetric_mechanism("revolute", EI=3.0)
    pose = (0.05, 0.02, math.radians(20))
    check_scale_invariance((m, pose, (0.1, -0.05, 0.01)), 2.0**-7, 2.0**9)


# ======================================================================================
# (c) IK -> FK round trip
# ======================================================================================
def check_round_trip(problem, pick: int):
    mech, pose, load = problem
    ik = flexkin.ik(mech, pose, load=load, max_mode=MAX_MODE)
    good = [s for s in ik.solutions if all(abs(r.k) < 1 - 1e-6 for r in s.rods)]
    assume(good)
    sol = good[pick % len(good)]
    note(f"IK solution {sol.mode_label}, inputs {sol.inputs!r}")
    fk = flexkin.fk(mech, sol.inputs, load=load, max_mode=MAX_MODE)
    count("(c) IK->FK round trips")
    count("(c) FK solutions verified", len(fk))
    L = mech.length_scale
    bad = verification_problems(mech, fk.solutions, load)
    assert not bad, f"{len(bad)} of {len(fk)} FK solutions fail the ODE verification: {bad[:5]}"
    for s in fk.solutions:
        assert np.allclose(s.inputs, sol.inputs, rtol=0, atol=1e-12 * max(L, 1.0)), "FK changed the inputs"
    found = any(abs(s.pose[0] - pose[0]) < 1e-8 * L and abs(s.pose[1] - pose[1]) < 1e-8 * L
                and abs(math.remainder(s.pose[2] - pose[2], 2 * math.pi)) < 1e-8 for s in fk.solutions)
    if not fk.complete:
        count("(c) FK searches incomplete")
        event("fk incomplete")
        note(f"FK incomplete: {fk.message}")
    assert found or not fk.complete, (
        f"FK at the inputs of IK solution {sol.mode_label} does not find its pose; FK poses: "
        f"{[tuple(round(v, 6) for v in s.pose) for s in fk.solutions][:10]}")


@FAST_FK
@given(problems(kinds=("PPP", "RRR", "mixed")), st.integers(0, 3))
def test_ik_fk_round_trip(problem, pick):
    check_round_trip(problem, pick)


@pytest.mark.slow
@SLOW
@given(problems(), st.integers(0, 50))
def test_ik_fk_round_trip_slow(problem, pick):
    check_round_trip(problem, pick)


# ======================================================================================
# (d) the loader rejects random bad files cleanly
# ======================================================================================
with open(EXAMPLES / "mixed_legs.toml", "rb") as _fh:
    BASE_DOC = tomllib.load(_fh)


def _leaves(obj, prefix=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield prefix + (k,)
            yield from _leaves(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield prefix + (i,)
            yield from _leaves(v, prefix + (i,))


LEAVES = list(_leaves(BASE_DOC))

toml_scalars = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.integers(-10**400, 10**400),
    st.booleans(), st.text(max_size=12), st.datetimes(), st.dates(), st.times(),
)
toml_values = st.recursive(toml_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=3)), max_leaves=8)


def _assert_clean(exc: MechanismError, source: str) -> None:
    msg = str(exc)
    assert isinstance(exc, ValueError)
    assert msg.startswith(source + ": "), msg
    assert "\n" not in msg and "Traceback" not in msg, msg
    assert "invalid mechanism description" not in msg, f"unhandled exception inside the loader: {msg}"


def check_mutated_dict(path, value, delete):
    doc = copy.deepcopy(BASE_DOC)
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    count("(d) mutated documents")
    try:
        m = mechanism_from_dict(doc, source="fuzz.toml")
    except MechanismError as exc:
        _assert_clean(exc, "fuzz.toml")
        count("(d) ... rejected")
        return
    assert isinstance(m, Mechanism)


@FAST_LOADER
@given(st.sampled_from(LEAVES), toml_values, st.booleans())
def test_loader_mutated_documents(path, value, delete):
    check_mutated_dict(path, value, delete)


@pytest.mark.slow
@settings(max_examples=2000, **COMMON)
@given(st.sampled_from(LEAVES), toml_values, st.booleans())
def test_loader_mutated_documents_slow(path, value, delete):
    check_mutated_dict(path, value, delete)


# the same, through real files: random bad values in the TOML text of a numeric key
_NUMERIC_LINES = {"length = 0.9": "rod.length", "E = 68e9": "rod.E", "radius = 1.5e-3": "rod.radius",
                  "angle = 5.0": "leg[1].angle", "moment = 0.002": "load.moment", "max_strain = 0.04": "limits.max_strain"}
_NOT_A_NUMBER = ["nan", "inf", "-inf", "+nan", "1e400", "-1e400", "true", '"1.0"', "[1.0]", "{}", "0x1p3",
                 "1979-05-27", "07:32:00", "1" + "0" * 400, "'x'", "[]", "1.", ".5", "1e", "--1"]
_NON_POSITIVE = st.one_of(st.sampled_from(["0", "-1", "-0.0", "-0", "0.0"]),
                          st.floats(max_value=0.0, allow_nan=False, allow_infinity=False).map(repr))
_SIGNED_OK = {"leg[1].angle", "load.moment"}  # any finite number is valid there


@st.composite
def bad_files(draw):
    """The mixed example with one numeric key given a bad literal: (text, key path, literal)."""
    text = (EXAMPLES / "mixed_legs.toml").read_text(encoding="utf-8")
    line = draw(st.sampled_from(sorted(_NUMERIC_LINES)))
    key = _NUMERIC_LINES[line]
    lit = draw(st.sampled_from(_NOT_A_NUMBER) if key in _SIGNED_OK
               else st.one_of(st.sampled_from(_NOT_A_NUMBER), _NON_POSITIVE))
    return text.replace(line, line.split(" = ")[0] + " = " + lit, 1), key, lit


def check_bad_file(tmp_path, case):
    text, key, lit = case
    p = tmp_path / "bad.toml"
    p.write_text(text, encoding="utf-8")
    count("(d) bad files")
    with pytest.raises(MechanismError) as info:
        load_mechanism(p)
    _assert_clean(info.value, str(p))
    msg = str(info.value)
    assert key in msg or "malformed TOML" in msg, (lit, msg)


@FAST_LOADER
@given(bad_files())
def test_loader_bad_files(tmp_path, case):
    check_bad_file(tmp_path, case)


@pytest.mark.slow
@SLOW
@given(bad_files())
def test_loader_bad_files_slow(tmp_path, case):
    check_bad_file(tmp_path, case)


@FAST_LOADER
@given(st.one_of(st.binary(max_size=300), st.text(max_size=300).map(lambda t: t.encode("utf-8"))))
def test_loader_arbitrary_bytes(tmp_path, data):
    p = tmp_path / "junk.toml"
    p.write_bytes(data)
    count("(d) arbitrary byte files")
    with pytest.raises(MechanismError) as info:
        load_mechanism(p)
    _assert_clean(info.value, str(p))


# ======================================================================================
# (e) determinism
# ======================================================================================
def fingerprint(res) -> list[tuple]:
    """Every number of every solution, bitwise (float.hex), in the reported order."""
    out = []
    for s in res.solutions:
        nums = list(s.pose) + list(s.inputs) + [s.residual, s.energy]
        for r in s.rods:
            nums += [r.k, r.psi, r.tip_force[0], r.tip_force[1], r.base_moment, r.energy]
        out.append((s.modes, s.stable, s.stability_index, tuple(float(v).hex() for v in nums)))
    return out


def check_deterministic(problem):
    mech, pose, load = problem
    a = flexkin.ik(mech, pose, load=load, max_mode=MAX_MODE)
    twin = Mechanism(name=mech.name, legs=mech.legs, platform=mech.platform, load=mech.load)  # equal, not identical
    b = flexkin.ik(twin, pose, load=load, max_mode=MAX_MODE)
    count("(e) determinism examples")
    assert len(a) == len(b)
    assert fingerprint(a) == fingerprint(b)
    assert json.dumps(a.to_dict(), sort_keys=True) == json.dumps(b.to_dict(), sort_keys=True)


@settings(max_examples=4, **COMMON)
@given(problems())
def test_ik_is_deterministic(problem):
    check_deterministic(problem)


@pytest.mark.slow
@settings(max_examples=100, **COMMON)
@given(problems())
def test_ik_is_deterministic_slow(problem):
    check_deterministic(problem)


def test_ik_json_identical_across_processes():
    """A fresh process (``flexkin ik --json``) prints exactly the in-process result."""
    from flexkin.cli import main
    import contextlib
    import io
    import shutil

    argv = ["ik", str(EXAMPLES / "mixed_legs.toml"), "--pose", "0.02", "-0.01", "15", "--json"]
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    exe = shutil.which("flexkin")
    cmd = [exe] if exe else [sys.executable, "-c", "import sys; from flexkin.cli import main; sys.exit(main())"]
    p = subprocess.run(cmd + argv, capture_output=True, text=True, timeout=300, cwd=str(ROOT))
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout) == json.loads(out.getvalue())
    assert p.stdout == out.getvalue()
