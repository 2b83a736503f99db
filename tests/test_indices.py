"""Performance indices (flexkin.analysis.indices) against independent references.

* the output stiffness against finite differences of the FK equilibrium under small added loads;
* the velocity ellipse/ellipsoid against the image of many unit input rates under J_IK;
* the peak curvature against dense samples of the rod's curvature, the strain as radius x it;
* the scaling law of every index when all lengths are scaled by s (EI by s^2, the moment by s);
* C3 symmetry: a symmetric mechanism's indices at a pose and at the pose turned by 120 deg;
* the singularity distances on constructed maps and paths (exact values and the unknown rule).
"""

from __future__ import annotations

import json
import math
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

import flexkin
from flexkin.analysis.indices import index_arrays, performance_indices, singularity_distance_along_path
from flexkin.mechanism import mechanism_from_dict, symmetric_mechanism
from flexkin.solve.workspace import FAILED, REACHED, SEAM, UNSTABLE, singularity_distance_map


def _stable(res):
    return [s for s in res.solutions if s.stable is True]


def _fib_sphere(n: int) -> np.ndarray:
    """n nearly uniform unit vectors in R^3 (Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(1 - z * z)
    a = math.pi * (1 + 5**0.5) * k
    return np.stack([r * np.cos(a), r * np.sin(a), z], -1)


def test_stiffness_matches_fk_under_small_added_loads(examples_dir):
    """C = K^-1: the pose moves by C dW when the load grows by dW, the inputs held (flexkin.fk)."""
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    sol = _stable(flexkin.ik(mech, (0.05, -0.03, 0.2)))[0]
    ind = sol.indices
    eps = 1e-3  # N and N m, against forces of order EI/L^2 = 1 N
    C_fd = np.zeros((3, 3))
    for a in range(3):
        moved = []
        for sign in (1.0, -1.0):
            w = np.zeros(3)
            w[a] = sign * eps
            fk = flexkin.fk(mech, sol.inputs, load=w, max_mode=max(sol.modes))
            poses = np.array([s.pose for s in fk.solutions])
            moved.append(poses[np.argmin(np.linalg.norm(poses - np.array(sol.pose), axis=1))])
        C_fd[:, a] = (moved[0] - moved[1]) / (2 * eps)
    assert np.max(np.abs(C_fd - ind.compliance)) <= 1e-3 * np.max(np.abs(ind.compliance))
    assert np.allclose(ind.stiffness @ ind.compliance, np.eye(3), atol=1e-9)
    assert np.allclose(ind.stiffness, ind.stiffness.T, atol=1e-9 * np.max(np.abs(ind.stiffness)))
    assert np.all(np.linalg.eigvalsh(ind.stiffness) > 0)  # stable: positive definite
    # the scalar summaries from their definitions
    assert ind.force_stiffness == pytest.approx(1 / np.linalg.eigvalsh(C_fd[:2, :2])[-1], rel=1e-3)
    assert ind.moment_stiffness == pytest.approx(1 / C_fd[2, 2], rel=1e-3)


@pytest.mark.parametrize("example, pose, Lc", [("unit_3rfr.toml", (0.05, -0.03, 0.2), None),
                                               ("mixed_legs.toml", (0.0, 0.0, 0.1), None),
                                               ("mixed_legs.toml", (0.0, 0.0, 0.1), 0.3)])
def test_velocity_ellipse_is_the_image_of_the_unit_input_ball_under_J_IK(example, pose, Lc, examples_dir):
    mech = flexkin.load_mechanism(examples_dir / example)
    res = flexkin.ik(mech, pose)
    sols = [s for s in res.solutions if s.jacobian is not None and s.jacobian.J_IK is not None]
    assert sols
    L = mech.length_scale if Lc is None else Lc
    angular = np.array([leg.actuation == "revolute" for leg in mech.legs])
    U = _fib_sphere(20000)
    for sol, ind in zip(sols, performance_indices(sols, characteristic_length=Lc)):
        jac = sol.jacobian  # dimensionless J_IK in L_ref units (flexkin.analysis.jacobian)
        su = np.where(angular, 1.0, jac.L_ref)
        J = np.diag([jac.L_ref, jac.L_ref, 1.0]) @ jac.J_IK @ np.diag(1 / su)  # SI: d(x, y, theta)/d(rho)
        s = np.where(angular, 1.0, L)
        V = (J @ np.diag(s) @ U.T).T                                      # images of unit input rates
        # ellipse of P: every image lies inside, the extreme ones on it, along the stated angle
        a, b = ind.ellipse_axes
        e1 = np.array([math.cos(ind.ellipse_angle), math.sin(ind.ellipse_angle)])
        e2 = np.array([-e1[1], e1[0]])
        q = (V[:, :2] @ e1 / a) ** 2 + (V[:, :2] @ e2 / b) ** 2
        assert q.max() <= 1 + 1e-9 and q.max() > 0.995
        assert np.max(np.abs(V[:, :2] @ e1)) == pytest.approx(a, rel=1e-3)
        assert np.max(np.abs(V[:, :2] @ e2)) == pytest.approx(b, rel=1e-3)
        # ellipsoid of J_h: semi-axes from the eigenvalues of J_h J_h^T, cond and volume
        Vh = V / np.array([L, L, 1.0])
        Jh = np.diag([1 / L, 1 / L, 1.0]) @ J @ np.diag(s)
        lam = np.sort(np.linalg.eigvalsh(Jh @ Jh.T))[::-1]
        assert ind.ellipsoid_axes == pytest.approx(np.sqrt(lam), rel=1e-9)
        assert np.max(np.linalg.norm(Vh, axis=1)) == pytest.approx(ind.ellipsoid_axes[0], rel=1e-3)
        assert ind.cond == pytest.approx(math.sqrt(lam[0] / lam[2]), rel=1e-9)
        assert ind.manipulability == pytest.approx(abs(np.linalg.det(Jh)), rel=1e-9)
        if Lc is None:  # the default L_c is the length scale of the Jacobians' own condition number
            assert ind.cond == pytest.approx(jac.cond, rel=1e-8)


def test_peak_curvature_and_strain(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "mixed_legs.toml")
    res = flexkin.ik(mech, (0.0, 0.0, 0.1))
    assert len(res.solutions) >= 2
    radii = np.array([leg.rod.radius for leg in mech.legs])
    for sol, f in zip(res.solutions, res.feasibility()):
        ind = sol.indices
        dense = np.array([np.max(np.abs(r.curvature(4001))) for r in sol.rods])
        assert np.all(ind.curvature >= dense * (1 - 1e-9))  # the closed form is the peak
        assert ind.curvature == pytest.approx(dense, rel=2e-3)
        assert ind.strain == pytest.approx(radii * ind.curvature, rel=1e-12)
        assert ind.max_strain == pytest.approx(f.max_strain, rel=1e-9)  # feasibility's convention
    # without radii: None in the JSON, never NaN
    unit = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    d = flexkin.ik(unit, (0.05, -0.03, 0.2)).solutions[0].to_dict()["indices"]
    assert d["peak_strain"] == [None, None, None] and d["max_strain"] is None
    assert all(v > 0 for v in d["peak_curvature"])


def _scaled(data: dict, s: float, radius: float) -> dict:
    """The unit 3-RFR with every length x s, EI x s^2, a load (F fixed, M x s) and a radius x s."""
    return {"name": f"scaled {s}", "rod": {"length": s * data["rod"]["length"], "EI": s**2 * data["rod"]["EI"],
                                           "radius": s * radius},
            "platform": {"attach": [[s * x, s * y] for x, y in data["platform"]["attach"]]},
            "leg": [{"actuation": "revolute", "origin": [s * leg["origin"][0], s * leg["origin"][1]]}
                    for leg in data["leg"]],
            "load": {"force": [0.3, -0.2], "moment": 0.05 * s}}


def test_indices_scale_with_the_mechanism(examples_dir):
    """All lengths x s with EI x s^2 and the moment x s (so F L^2 / EI and M L / EI are fixed):
    the same equilibria, scaled.  Then K_tt = EI/L^3 x 1/s, K_tr x 1, K_rr = EI/L x s; the
    homogeneous condition number and manipulability are unchanged (L_c = the mean rod length
    scales too), the velocity ellipse (m/s per L_c/s) x s, curvature x 1/s, strain x 1."""
    data = tomllib.loads((examples_dir / "unit_3rfr.toml").read_text())
    pose = np.array([0.05, -0.03, 0.2])
    out = {}
    for s in (1.0, 3.0):
        mech = mechanism_from_dict(_scaled(data, s, 0.01), source=f"scaled {s}")
        res = flexkin.ik(mech, (s * pose[0], s * pose[1], pose[2]))
        sols = sorted(res.solutions, key=lambda q: tuple(np.round(q.inputs, 6)))
        out[s] = (sols, performance_indices(sols))
    (a, ia), (b, ib) = out[1.0], out[3.0]
    assert len(a) == len(b) >= 4
    D = np.diag([1 / 3, 1 / 3, 1.0])  # one 1/s per translational row and column
    for sa, sb, x, y in zip(a, b, ia, ib):
        assert np.allclose(sb.inputs, sa.inputs, atol=1e-7)
        expect = 3.0 * D @ x.stiffness @ D  # EI / L x s
        assert np.allclose(y.stiffness, expect, rtol=1e-6, atol=1e-8 * np.max(np.abs(expect)))
        assert y.cond == pytest.approx(x.cond, rel=1e-6)
        assert y.manipulability == pytest.approx(x.manipulability, rel=1e-6)
        assert y.ellipse_axes == pytest.approx(3.0 * x.ellipse_axes, rel=1e-6)
        assert y.curvature == pytest.approx(x.curvature / 3.0, rel=1e-6)
        assert y.strain == pytest.approx(x.strain, rel=1e-6)
        # NaN (not positive: unstable) at both sizes or neither
        assert y.force_stiffness == pytest.approx(x.force_stiffness / 3.0, rel=1e-6, nan_ok=True)
        assert y.moment_stiffness == pytest.approx(3.0 * x.moment_stiffness, rel=1e-6, nan_ok=True)


def test_c3_symmetry_of_a_symmetric_mechanism():
    """Turning a C3-symmetric mechanism's equilibrium by 120 deg about O gives an equilibrium: P
    turns, and since the platform's attach points turn into each other (b_i+1 = Rot(120) b_i)
    with the legs, the orientation theta is unchanged.  Then K -> R K R^T with R = diag(Rot(120),
    1), the ellipse turns by 120 deg, the scalar indices and the rods' curvatures (permuted) are
    unchanged."""
    mech = symmetric_mechanism("revolute")
    c, s = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
    R2 = np.array([[c, -s], [s, c]])
    R = np.eye(3)
    R[:2, :2] = R2
    p = np.array([0.06, -0.02, 0.25])
    q = np.concatenate([R2 @ p[:2], [p[2]]])
    A = flexkin.ik(mech, tuple(p)).solutions
    B = flexkin.ik(mech, tuple(q)).solutions
    assert len(A) == len(B) >= 4
    IA, IB = performance_indices(A), performance_indices(B)
    used = set()
    for sa, x in zip(A, IA):
        match = [k for k, (sb, y) in enumerate(zip(B, IB)) if k not in used and abs(sb.energy - sa.energy) < 1e-9
                 and np.allclose(y.curvature, np.roll(x.curvature, 1), rtol=1e-7)]  # leg i -> leg i+1
        assert len(match) == 1, sa
        k = match[0]
        used.add(k)
        y = IB[k]
        scale = np.max(np.abs(x.stiffness))
        assert np.allclose(y.stiffness, R @ x.stiffness @ R.T, atol=1e-7 * scale)
        for name in ("cond", "manipulability", "force_stiffness", "moment_stiffness"):
            assert getattr(y, name) == pytest.approx(getattr(x, name), rel=1e-7, nan_ok=True), name
        assert y.ellipse_axes == pytest.approx(x.ellipse_axes, rel=1e-7)
        turn = (y.ellipse_angle - x.ellipse_angle - 2 * math.pi / 3) % math.pi
        assert min(turn, math.pi - turn) < 1e-6 or abs(x.ellipse_axes[0] - x.ellipse_axes[1]) < 1e-6


def test_indices_in_the_json_and_bad_length(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    res = flexkin.ik(mech, (0.05, -0.03, 0.2))
    doc = json.loads(json.dumps(res.to_dict(feasibility=False), allow_nan=False))
    for e, sol in zip(doc["solutions"], res.solutions):
        ind = e["indices"]
        assert set(ind["units"]) >= {"stiffness", "compliance", "velocity_ellipse", "condition_number"}
        assert np.allclose(ind["stiffness"], sol.indices.stiffness)
        assert ind["characteristic_length"] == mech.length_scale
        assert ind["singularity_distance"] is None  # a property of a map or a path, not of one pose
        if sol.stable:
            assert ind["force_stiffness"] > 0 and ind["velocity_ellipse"]["semi_axes"][0] > 0
    with pytest.raises(ValueError, match="characteristic_length"):
        performance_indices(res.solutions, characteristic_length=-1.0)
    with pytest.raises(ValueError, match="charts"):
        index_arrays(mech, np.zeros((2, 5)), np.zeros((2, 3)))


# ---- singularity distances ---------------------------------------------------------------------
def _map(status):
    status = np.asarray(status, np.int8)
    reached = status == REACHED
    bik = np.zeros_like(reached)
    bfk = np.zeros_like(reached)
    for dj, di in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        nb = np.full(status.shape, -1)
        nb[max(dj, 0):status.shape[0] + min(dj, 0), max(di, 0):status.shape[1] + min(di, 0)] = \
            status[max(-dj, 0):status.shape[0] + min(-dj, 0), max(-di, 0):status.shape[1] + min(-di, 0)]
        bik |= reached & (nb == FAILED)
        bfk |= reached & (nb == UNSTABLE)
    return SimpleNamespace(status=status, boundary_ik=bik, boundary_fk=bfk)


def test_singularity_distance_on_a_map():
    # 5 x 9 grid: columns 0..6 reached, column 7 across an FK singularity, column 8 unvisited;
    # rows 0 and 4 and column 0 are the grid's edge (beyond it: unknown)
    st = np.full((5, 9), REACHED)
    st[:, 7] = UNSTABLE
    st[:, 8] = 0
    h = 0.1
    d = singularity_distance_map(_map(st), h)
    mid = d[2]
    assert mid[4:7] == pytest.approx(h * (6 - np.arange(4, 7)) + h / 2)  # to the boundary cells, + h/2
    # nearer to the grid's edge than to the crossing: unknown
    assert np.isnan(mid[:4]).all()
    # on the edge rows a singularity beyond the grid may be nearer: unknown except next to the crossing
    assert np.isnan(d[0, :6]).all() and d[0, 6] == pytest.approx(h / 2)
    assert np.isnan(d[:, 7:]).all()
    # a seam cell is unknown ground: cells nearer to it than to the crossing are unknown
    st2 = st.copy()
    st2[2, 1] = SEAM
    d2 = singularity_distance_map(_map(st2), h)
    assert np.isnan(d2[2, 0]) and np.isnan(d2[2, 2]) and d2[2, 5] == pytest.approx(1.5 * h)
    # no singularity found at all: unknown everywhere
    assert np.isnan(singularity_distance_map(_map(np.full((3, 3), REACHED)), h)).all()


def test_singularity_distance_along_a_path():
    t = np.linspace(0.0, 1.0, 11)
    poses = np.stack([t, np.zeros_like(t), 0.5 * t], -1)   # ds = sqrt(1 + (0.5 L_c)^2) dt
    sing_ik = 0.62 - t                                      # crosses zero at t = 0.62
    sing_fk = np.ones_like(t)
    L = 2.0
    d = singularity_distance_along_path(poses, sing_ik, sing_fk, L)
    v = math.sqrt(1 + (0.5 * L) ** 2)
    known = np.abs(t - 0.62) <= np.minimum(t, 1 - t) + 1e-12
    assert d[known] == pytest.approx(v * np.abs(t[known] - 0.62))
    assert np.isnan(d[~known]).all() and known.sum() == 5
    assert np.isnan(singularity_distance_along_path(poses, sing_fk, sing_fk, L)).all()
