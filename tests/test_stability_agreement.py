"""The two stability methods agree on every solution of the IK/FK test mechanisms.

flexkin's method (exact: Jacobi conjugate points of each rod with its tip pinned + reduced
Hessian of the potential over the pose, :mod:`flexkin.kinematics.stability`) against the
independent oracle ``tests/stability_oracle.py`` (a converged finite-difference
discretisation of the rods with the constrained Hessian, index from the KKT inertia).
Compared: the verdict and the Morse index (number of unstable directions).  Solutions the
oracle cannot resolve (two resolutions disagree, or |smallest eigenvalue| < 1e-3, i.e. at
a singularity within the discretisation error) are counted and skipped.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

import flexkin

sys.path.insert(0, os.path.dirname(__file__))
import stability_oracle as S  # noqa: E402

try:
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}


def _compare(mech, sols, load, tag):
    agree, skipped, n_stable = 0, 0, 0
    for s in sols:
        r = S.solution_stability(mech, s, load)
        if not r.converged or abs(r.min_eig) < 1e-3:
            skipped += 1
            continue
        assert s.stable == r.stable, (tag, s.mode_label, s.inputs, s.stability_index, r.index, r.min_eig)
        assert s.stability_index == r.index, (tag, s.mode_label, s.inputs, s.stability_index, r.index)
        agree += 1
        n_stable += bool(s.stable)
    REPORT[f"stability agreement: {tag}"] = f"{agree} agree ({n_stable} stable), {skipped} unresolved by the oracle"
    assert agree >= max(1, len(sols) - skipped)
    return agree, skipped


@pytest.mark.parametrize("example, pose", [("unit_3rfr.toml", (0.05, 0.02, np.radians(20))),
                                           ("unit_3rfr.toml", (0.2, 0.0, 0.0)),
                                           ("mixed_legs.toml", (0.02, -0.01, np.radians(15)))])
def test_ik_solutions_two_methods_agree(example, pose, examples_dir):
    mech = flexkin.load_mechanism(examples_dir / example)
    res = flexkin.ik(mech, pose)
    _compare(mech, res.solutions, res.load, f"IK {example} at {np.round(pose, 3).tolist()}")


def test_table1_fk_solutions_two_methods_agree(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    res = flexkin.fk(mech, (0.025, 0.025, 0.025), load=(0, 0, 0))
    agree, _ = _compare(mech, res.solutions, res.load, "FK prototype rho = 25 mm")
    assert agree >= 2


@pytest.mark.slow
@pytest.mark.parametrize("example, pose", [("unit_3pfr.toml", (0.05, 0.02, np.radians(20))),
                                           ("unit_3pfr_length.toml", (0.05, 0.02, np.radians(20))),
                                           ("unit_3rfr.toml", (0.0, 0.05, 0.0)),
                                           ("prototype_3pfr.toml", (0.0, 0.0, np.radians(90))),
                                           ("prototype_3pfr.toml", (0.0, 0.0, np.radians(60)))])
def test_more_ik_solutions_two_methods_agree(example, pose, examples_dir):
    mech = flexkin.load_mechanism(examples_dir / example)
    res = flexkin.ik(mech, pose)
    _compare(mech, res.solutions, res.load, f"IK {example} at {np.round(pose, 3).tolist()}")


@pytest.mark.slow
def test_fk_solutions_two_methods_agree(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")
    ik = flexkin.ik(mech, (0.05, 0.02, np.radians(20)))
    res = flexkin.fk(mech, ik.solutions[0].inputs)
    _compare(mech, res.solutions, res.load, "FK unit_3rfr")
