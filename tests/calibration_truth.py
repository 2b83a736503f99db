"""Synthetic measurements of a perturbed ("true") mechanism for the calibration tests.

The true rows are computed by the INDEPENDENT oracles of this directory, never by the code under
test: an IK row's inputs by the shooting oracle of ``ik_oracle`` (RK4 Newton on its own 12
equations, polished with DOP853), an FK row's pose by the tip-anchored shooting of ``fk_oracle``.
flexkin's nominal solution only gives those Newton iterations their starting point.

The oracles rebuild every clamp from SPEC §2 by hand and know nothing of ``[[leg]] offset``: the
true input offsets are applied here, by hand, the way SPEC §4 defines them -- the leg behaves as
if its input were ``u + offset`` -- so an IK row's measured input is ``u_true - offset`` and an FK
row's physical input is ``u_commanded + offset``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

import flexkin
from flexkin.mechanism.model import circular_EI
from fk_oracle import FKSystem, TipSystem, _build, chart_y, tip_newton, tip_polish
from ik_oracle import Geom, _newton, _polish, _System, solution_z

__all__ = ["Truth", "perturbed", "true_rows", "noisy_csv_rows"]


@dataclass(frozen=True)
class Truth:
    """A perturbation: input offsets (internal units), E factor, origin shifts (m) per leg."""

    offsets: tuple[float, float, float] = (0.0, 0.0, 0.0)
    E_factor: float = 1.0
    origin_shift: tuple[tuple[float, float], ...] = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))


def perturbed(mech, truth: Truth):
    """The true mechanism WITHOUT offsets (the oracles ignore them; they are applied by hand)."""
    legs = []
    for leg, d in zip(mech.legs, truth.origin_shift):
        rod = leg.rod
        if truth.E_factor != 1.0:
            E = rod.E * truth.E_factor
            rod = dataclasses.replace(rod, E=E, EI=circular_EI(E, rod.radius))
        legs.append(dataclasses.replace(leg, origin=(leg.origin[0] + d[0], leg.origin[1] + d[1]), rod=rod, offset=0.0))
    return dataclasses.replace(mech, legs=tuple(legs))


def _nominal_stable(res):
    st = [s for s in res.solutions if s.stable is True]
    return st[0] if st else None


def _oracle_ik(truth_mech, pose, load, start):
    sys_ = _System(Geom.of(truth_mech), pose, np.asarray(load, float))
    z0 = solution_z(truth_mech, start, pose, load)[None]
    z, rn, _ = _newton(sys_, z0, n_iter=40, n_steps=300, tol=1e-10)
    zp, rp = _polish(sys_, z)
    if rp[0] > 1e-9:
        return None
    return zp[0, 9:12] * sys_.us


def _oracle_fk(truth_mech, u_phys, load, start):
    fs = FKSystem(truth_mech, u_phys, np.asarray(load, float))
    ts = TipSystem(fs)
    forces = np.array([r.tip_force for r in start.rods])[None]
    tips = np.array([r.tip_angle for r in start.rods])[None]
    y0 = chart_y(fs, forces, tips, np.asarray(start.pose, float)[None])
    y, rn, _, _ = tip_newton(ts, y0, n_iter=40, n_steps=256)
    yp, rp = tip_polish(ts, y)
    if rp[0] > 1e-9:
        return None
    return np.asarray(_build(fs, ts, yp)[0].pose, float)


def true_rows(mech, truth: Truth, ik_poses, fk_poses, loads):
    """Noise-free true measurements.

    Parameters
    ----------
    mech : Mechanism
        The nominal mechanism (what the calibration starts from).
    truth : Truth
    ik_poses : list of (x, y, theta_rad)
        Commanded poses of the IK rows.
    fk_poses : list of (x, y, theta_rad)
        Poses whose nominal stable IK solution gives the FK rows' commanded inputs.
    loads : list of (fx, fy, mz)
        One load per row, IK rows first.

    Returns
    -------
    list of dict
        ``kind``, ``u`` (commanded/measured inputs, internal units), ``pose`` (m, m, rad), ``load``.
    """
    tm = perturbed(mech, truth)
    off = np.asarray(truth.offsets, float)
    rows = []
    k = 0
    for pose in ik_poses:
        w = np.asarray(loads[k], float)
        k += 1
        start = _nominal_stable(flexkin.ik(mech, pose, w, max_mode=1))
        assert start is not None, f"no stable nominal IK at {pose}"
        u_true = _oracle_ik(tm, pose, w, start)
        assert u_true is not None, f"oracle IK failed at {pose}"
        rows.append({"kind": "ik", "u": u_true - off, "pose": np.asarray(pose, float), "load": w})
    for pose in fk_poses:
        w = np.asarray(loads[k], float)
        k += 1
        start = _nominal_stable(flexkin.ik(mech, pose, w, max_mode=1))
        assert start is not None, f"no stable nominal IK at {pose}"
        u_cmd = np.asarray(start.inputs, float)
        p_true = _oracle_fk(tm, u_cmd + off, w, start)
        assert p_true is not None, f"oracle FK failed at inputs {u_cmd + off}"
        rows.append({"kind": "fk", "u": u_cmd, "pose": p_true, "load": w})
    return rows


def noisy_csv_rows(mech, rows, rng, sigma_xy, sigma_th_deg, sigma_u):
    """Measurement rows (the CSV's columns, display units) with Gaussian noise on the measured
    quantity of each row (the pose of FK rows, the inputs of IK rows)."""
    out = []
    for r in rows:
        u = np.array(r["u"], float)
        p = np.array(r["pose"], float)
        if r["kind"] == "ik":
            u = u + rng.normal(0.0, sigma_u, 3)
        else:
            p = p + np.array([rng.normal(0, sigma_xy), rng.normal(0, sigma_xy),
                              math.radians(rng.normal(0, sigma_th_deg))])
        ud = [float(leg.to_display(v)) for leg, v in zip(mech.legs, u)]
        out.append({"kind": r["kind"], "u1": ud[0], "u2": ud[1], "u3": ud[2], "x": p[0], "y": p[1],
                    "theta_deg": math.degrees(p[2]), "fx": r["load"][0], "fy": r["load"][1], "mz": r["load"][2],
                    "sigma_u": sigma_u, "sigma_xy": sigma_xy, "sigma_theta_deg": sigma_th_deg})
    return out


# ---- a vertical prototype under its own weight (Cosserat truth) ------------------------------
def cosserat_fk_truth(truth_mech, u_phys, near_theta, params, gravity, Ns=(24, 48)):
    """The pose of a true mechanism with weight at physical inputs ``u_phys``, by the independent
    discrete-beam oracle (``cosserat_oracle``, Richardson-extrapolated over ``Ns``), started from
    flexkin's Kirchhoff FK solution nearest to the orientation ``near_theta`` refined into the
    Cosserat model (the start only).  The oracle knows nothing of input offsets: ``u_phys`` are
    the physical inputs."""
    import cosserat_oracle as oracle
    from flexkin.cosserat import refine, rod_shape
    from flexkin.cosserat.params import line_loads

    fk = flexkin.fk(truth_mech, u_phys, max_mode=1)
    st = [s for s in fk.solutions if s.stable is True]
    sol = min(st, key=lambda s: abs(math.remainder(s.pose[2] - near_theta, 2 * math.pi)))
    ref = refine(truth_mech, [sol], params=params, gravity=gravity, problem="fk", stability=False,
                 born_search=False).solutions[0]
    assert ref.reached
    f = line_loads(tuple(params), gravity, None)
    poses = []
    for N in Ns:
        rods, shapes = [], []
        for i, leg in enumerate(truth_mech.legs):
            rr, p = ref.rods[i], params[i]
            rods.append(oracle.OracleRod(clamp=rr.clamp, clamp_angle=rr.clamp_angle, length=rr.length,
                                         EI=leg.rod.EI, EA=p.EA, kGA=p.GA * p.shear_coefficient, load=tuple(f[i])))
            shp = rod_shape(rr.clamp, rr.clamp_angle, rr.length, leg.rod.EI, rr.base_force, rr.base_moment,
                            axial_compliance=p.axial_compliance, shear_compliance=p.shear_compliance,
                            line_load=f[i], n_points=4 * N + 1)
            sg = np.linspace(0.0, 1.0, 4 * N + 1)
            shapes.append(lambda s, shp=shp, sg=sg: (np.interp(s, sg, shp.points[:, 0]),
                                                     np.interp(s, sg, shp.points[:, 1]),
                                                     np.interp(s, sg, shp.theta)))
        out = oracle.solve_mechanism(rods, truth_mech.platform.attach, truth_mech.load, np.array(ref.pose), shapes,
                                     N=N, eigen=False)
        assert out.converged
        poses.append(np.asarray(out.pose, float))
    h2 = (Ns[0] / Ns[1]) ** 2
    pose = (poses[1] - h2 * poses[0]) / (1 - h2)      # Richardson: the O(h^2) error removed
    return pose, float(np.max(np.abs(pose - np.asarray(ref.pose))))
