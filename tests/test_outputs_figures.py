"""Figures a designer reads (issue 18): path determinants not flattened and their units stated, one id
per solution in every figure, pages instead of giant images, every file written named on stderr,
a readable geometric-condition figure, no moiré in the parameter space."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.cli import main

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"


@pytest.fixture(scope="module")
def proto():
    return flexkin.load_mechanism(EX / "prototype_3pfr.toml")


@pytest.fixture(scope="module")
def rfr():
    return flexkin.load_mechanism(EX / "unit_3rfr.toml")


# ---- path figure --------------------------------------------------------------------------
def test_path_figure_keeps_small_determinants_visible_and_states_units(proto):
    from flexkin.plot.path import plot_path

    res = flexkin.follow_path(proto, (0, 0, math.radians(90)), (0.01, 0, math.radians(90)), steps=3)
    assert res.complete
    # a real-scale design: det J_IK ~ -0.0014 while det J_FK = 1/det J_IK ~ -700
    d = -0.0014 * res.det_ik / res.det_ik[0]
    res = dataclasses.replace(res, det_ik=d, det_fk=1.0 / d)
    fig = plot_path(res)
    ax = next(a for a in fig.axes if any(ln.get_label() == "det J_IK" for ln in a.lines))
    line = next(ln for ln in ax.lines if ln.get_label() == "det J_IK")
    np.testing.assert_allclose(line.get_ydata(), d)          # the determinant itself, not a transform of it
    assert ax.get_yscale() == "symlog"
    lo, hi = ax.get_ylim()
    y_d, y_0 = ax.transData.transform([(0.5, d[0]), (0.5, 0.0)])[:, 1]
    height = abs(np.diff(ax.transAxes.transform([(0, 0), (0, 1)])[:, 1])[0])
    assert abs(y_d - y_0) > 0.03 * height, "det ~ -0.0014 is flattened onto zero"
    assert lo < 1.0 / d[0]  # the large one is on the axis too
    for text in (ax.get_ylabel(), ax.get_title(loc="left")):
        assert "dimensionless" in text and f"L_ref = {proto.length_scale:.4g} m" in text and "rad" in text
    sing = next(a for a in fig.axes if any(ln.get_label().startswith("sing_ik") for ln in a.lines))
    assert sing.get_yscale() == "linear"


def test_path_json_states_jacobian_units(capsys, tmp_path):
    code = main(["path", str(EX / "prototype_3pfr.toml"), "--from", "0", "0", "90", "--to", "0.01", "0", "90",
                 "--steps", "2", "--json"])
    assert code == 0
    import json

    d = json.loads(capsys.readouterr().out)
    assert "L_ref = 0.908 m" in d["jacobian_units"] and "rad" in d["jacobian_units"]


# ---- solution figures: ids and pages --------------------------------------------------------
def test_solution_panels_carry_ids_after_filtering(rfr):
    from flexkin.plot.solutions import plot_solution_pages

    res = flexkin.ik(rfr, (0.05, 0.02, math.radians(20)))
    sub = dataclasses.replace(res, solutions=res.solutions[1::2], _cache={})  # a filtered result: ids 2, 4, ...
    assert [s.id for s in sub.solutions] == list(range(2, len(res) + 1, 2))
    (fig,) = plot_solution_pages(sub)
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert [int(t.split()[0].lstrip("#")) for t in titles] == [s.id for s in sub.solutions]


def test_large_results_are_split_into_pages_and_every_file_is_printed(capsys, tmp_path, rfr, monkeypatch):
    res = flexkin.ik(rfr, (0.05, 0.02, math.radians(20)))
    sols = tuple(dataclasses.replace(s, id=k + 1) for k, s in enumerate(res.solutions * 3))  # 24 panels
    big = dataclasses.replace(res, solutions=sols, _cache={})
    from flexkin.plot import solutions as plot_solutions

    files = plot_solutions.write_solution_pages(big, tmp_path / "many.png")
    assert [f.name for f in files] == ["many.png", "many_2.png"]
    from matplotlib.image import imread

    h, w = imread(files[0]).shape[:2]
    assert h < 2200 and w < 2600, (w, h)  # a readable page of 20 panels, not a 2417 x 4907 px image
    # the CLI writes and prints every page (3 pages of 3 for the 8 solutions here)
    monkeypatch.setattr(plot_solutions, "PANELS_PER_PAGE", 3)
    code = main(["ik", str(EX / "unit_3rfr.toml"), "--pose", "0.05", "0.02", "20", "--plot", str(tmp_path / "p.png")])
    err = capsys.readouterr().err
    assert code == 0
    for name in ("p.png", "p_2.png", "p_3.png"):
        assert (tmp_path / name).is_file() and str(tmp_path / name) in err
    assert not (tmp_path / "p_4.png").exists()


# ---- workspace ---------------------------------------------------------------------------------
def test_workspace_cli_prints_what_it_saved(capsys, tmp_path):
    code = main(["workspace", str(EX / "unit_3rfr.toml"), "--theta", "20", "--theta", "40", "--step", "0.1",
                 "--bounds", "-0.6", "0.6", "-0.6", "0.6", "--first-aspect", "--jobs", "1",
                 "--save", str(tmp_path / "ws.npz"), "--plot", str(tmp_path / "ws.png")])
    err = capsys.readouterr().err
    assert code == 0
    for name in ("ws_theta20.npz", "ws_theta40.npz", "ws.png"):
        assert (tmp_path / name).is_file() and str(tmp_path / name) in err, name


# ---- geometric-condition curves -------------------------------------------------------------
def test_condition_curves_labels_do_not_overlap_and_legends_are_honest(proto):
    from flexkin.plot.curves import plot_curves

    res = flexkin.ik(proto, (0.0, 0.0, math.radians(90)))
    fig = plot_curves(res)
    renderer = fig.canvas.get_renderer()
    legends = []
    for ax in fig.axes:
        labels = [t for t in ax.texts if t.get_text() and t.get_transform() is not ax.transAxes]  # not footnotes
        assert labels
        boxes = [t.get_window_extent(renderer) for t in labels]
        for a in range(len(boxes)):
            for b in range(a + 1, len(boxes)):
                assert not boxes[a].overlaps(boxes[b]), (ax.get_title(), a, b)
        leg = ax.get_legend()
        texts = [t.get_text() for t in leg.get_texts()]
        modes = [t for t in texts if t.startswith("d-mode")]
        assert modes == sorted(modes)
        drawn = {ln.get_color() for ln in ax.lines if ln.get_linestyle() == "-" and len(ln.get_xdata()) > 1}
        for h, t in zip(leg.legend_handles, texts):
            if t.startswith("d-mode"):
                assert h.get_color() in drawn, t  # no legend entry without a curve
        legends.append(modes)
    # same order everywhere (the order of increasing d-mode)
    assert all(m == sorted(m) for m in legends)
    # every solution id is shown: on the plot or in a footnote
    shown = " ".join(t.get_text() for ax in fig.axes for t in ax.texts)
    for s in res.solutions[:10]:
        assert str(s.id) in shown


# ---- parameter space ----------------------------------------------------------------------------
def test_parameter_space_is_drawn_as_images_without_mesh_aliasing():
    from matplotlib.collections import QuadMesh

    from flexkin.plot.rod import plot_parameter_space

    fig = plot_parameter_space(2, "R", n=61)
    a1, a2 = fig.axes[:2]
    assert not any(isinstance(c, QuadMesh) for ax in (a1, a2) for c in ax.collections)
    (im1,) = a1.images
    (im2,) = a2.images
    z = np.ma.getdata(im1.get_array()).astype(float)
    mask = np.ma.getmaskarray(im1.get_array())
    n = z.shape[1]
    psi = (np.arange(n) + 0.5) * 2 * np.pi / n
    k = (np.arange(z.shape[0]) + 0.5) * 2 / z.shape[0] - 1
    K, PSI = np.meshgrid(k, psi, indexing="ij")
    kmin = np.abs(np.cos(PSI / 2))
    clear = np.abs(np.abs(K) - kmin) > 1e-9  # pixels not on the boundary itself
    assert np.array_equal(mask[clear], (np.abs(K) < kmin)[clear])  # no colour where no rod exists
    assert not np.ma.getmaskarray(im2.get_array()).any()
