"""The one angle-wrap convention, ``(-pi, pi]`` (flexkin.core.geometry2d.wrap_angle), in its
plain, array and compiled forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexkin.core.geometry2d import wrap_angle, wrap_to_pi


def test_the_interval_ends():
    assert wrap_to_pi(math.pi) == math.pi  # pi is kept
    assert wrap_to_pi(-math.pi) == math.pi  # -pi is not in (-pi, pi]
    assert wrap_to_pi(3 * math.pi) == pytest.approx(math.pi)
    assert wrap_to_pi(-3 * math.pi) == pytest.approx(math.pi)
    assert wrap_to_pi(0.0) == 0.0
    assert wrap_to_pi(2 * math.pi) == pytest.approx(0.0, abs=1e-15)
    assert wrap_to_pi(math.pi + 1e-9) == pytest.approx(-math.pi + 1e-9)
    assert wrap_to_pi(-math.pi + 1e-9) == pytest.approx(-math.pi + 1e-9)


def test_arrays_keep_their_shape_and_scalars_stay_floats():
    a = np.linspace(-10, 10, 24).reshape(2, 3, 4)
    w = wrap_to_pi(a)
    assert w.shape == a.shape
    assert np.all((w > -math.pi) & (w <= math.pi))
    assert np.allclose(np.exp(1j * w), np.exp(1j * a))
    assert isinstance(wrap_to_pi(1.0), float)
    assert isinstance(wrap_angle(7.0), float)


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1e4, max_value=1e4, allow_nan=False))
def test_wrap_is_the_representative_in_the_interval(a):
    w = wrap_to_pi(a)
    assert -math.pi < w <= math.pi
    k = (a - w) / (2 * math.pi)  # a differs from w by a whole number of turns
    assert abs(k - round(k)) <= 1e-9 * max(1.0, abs(a))
    assert wrap_angle(a) == w  # scalar and array forms agree exactly


def test_the_compiled_twin_agrees():
    from flexkin.core.geometry2d_kernels import wrap_angle as wrap_jit

    for a in (-math.pi, math.pi, 0.0, 3.5, -3.5, 1e3, -7 * math.pi, 2 * math.pi):
        assert wrap_jit(a) == wrap_angle(a)
