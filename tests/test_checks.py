"""Tests for minimanc.checks: the argument validators shared by dmp, quaternion, vagn and cam."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from minimanc import checks, engine

finite = dict(allow_nan=False, allow_infinity=False)


# --------------------------------------------------------------------------- float_tolerance


def test_float_tolerance_is_factor_times_eps_times_terms():
    for dt in (np.float16, np.float32, np.float64):
        for n in (1, 4, 100):
            assert checks.float_tolerance(dt, n) == checks.TOLERANCE_FACTOR * np.finfo(dt).eps * n
    ratio = checks.float_tolerance(np.float32) / checks.float_tolerance(np.float64)
    assert ratio == 2.0**29 and 5e8 < ratio < 6e8
    # integers and booleans convert exactly to float64
    assert checks.float_tolerance(np.int32, 3) == checks.float_tolerance(np.float64, 3)
    assert checks.float_tolerance("float32") == checks.float_tolerance(np.float32)


def test_float_tolerance_refuses_bad_arguments():
    with pytest.raises(ValueError, match="terms must be an integer >= 1, got terms=0"):
        checks.float_tolerance(np.float64, 0)
    with pytest.raises(ValueError, match="terms=2.5"):
        checks.float_tolerance(np.float64, 2.5)
    with pytest.raises(TypeError, match="dtype must be a NumPy dtype"):
        checks.float_tolerance(object(), 1)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 64), st.sampled_from([np.float32, np.float64]), st.integers(0, 2**31))
def test_a_normalised_distribution_is_within_its_tolerance(n, dtype, seed):
    # q / sum(q) in the dtype itself: the float64 sum of the result is within the tolerance
    q = np.random.default_rng(seed).dirichlet(np.ones(n)).astype(dtype)
    q = q / q.sum()
    assert abs(float(q.astype(np.float64).sum()) - 1.0) <= checks.float_tolerance(dtype, n)
    checks.check_distribution("q", q, n)


# --------------------------------------------------------------------------- value_dtype


def test_value_dtype_is_the_arrays_own_precision():
    x32 = np.random.default_rng(0).uniform(size=5).astype(np.float32)
    assert checks.value_dtype(x32) == np.float32
    assert checks.value_dtype(x32.astype(np.float64)) == np.float64
    assert checks.value_dtype(np.random.default_rng(0).uniform(size=5)) == np.float64
    assert checks.value_dtype(3) == np.float64 and checks.value_dtype([1, 2]) == np.float64
    assert checks.value_dtype(np.array([np.nan, 1e300])) == np.float64


# --------------------------------------------------------------------------- real / finite


@pytest.mark.parametrize("bad", ["10", None, b"1", {"a": 1}, [1.0, "x"], 1 + 2j,
                                 np.array([1 + 1j]), [[1.0], [1.0, 2.0]]])
def test_check_real_raises_type_error_naming_the_argument(bad):
    with pytest.raises(TypeError, match=r"gain must be a real number or array, got gain="):
        checks.check_real("gain", bad)
    with pytest.raises(TypeError, match=r"gain must be a real number or array"):
        checks.check_finite_if_concrete("gain", bad)


@pytest.mark.parametrize("bad, shown", [(np.nan, "nan"), (np.inf, "inf"),
                                        (np.array([1.0, -np.inf]), "-inf")])
def test_check_finite_names_the_first_bad_value(bad, shown):
    with pytest.raises(ValueError, match=rf"x must be finite, got x={shown}"):
        checks.check_finite("x", bad)


def test_check_positive_and_int():
    assert checks.check_positive("dt", 0.5) == 0.5
    with pytest.raises(ValueError, match=r"dt must be > 0, got dt=-1\.0"):
        checks.check_positive("dt", [1.0, -1.0])
    assert checks.check_int("n", 3, 1) == 3
    for bad in (0, 2.5, True, "3"):
        with pytest.raises(ValueError, match=f"n must be an integer >= 1, got n={bad!r}"):
            checks.check_int("n", bad, 1)


@settings(max_examples=100, deadline=None)
@given(st.integers(-5, 5), st.integers(0, 6),
       st.one_of(st.integers(-20, 20), st.integers(-20, 20).map(np.int64),
                 st.floats(-20, 20), st.booleans(), st.just("3"), st.none()))
def test_check_int_with_a_maximum_accepts_exactly_the_integers_in_range(lo, width, value):
    hi = lo + width
    is_int = isinstance(value, int | np.integer) and not isinstance(value, bool)
    if is_int and lo <= value <= hi:
        out = checks.check_int("k", value, lo, hi)
        assert out == value and type(out) is int
    else:
        with pytest.raises(ValueError, match=rf"^k must be an integer in \[{lo}, {hi}\], "
                                             rf"got k={re.escape(repr(value))}$"):
            checks.check_int("k", value, lo, hi)


def test_check_int_refuses_an_empty_range():
    with pytest.raises(ValueError, match=r"check_int\('k'\): maximum 0 < minimum 1"):
        checks.check_int("k", 1, 1, 0)


@pytest.mark.parametrize("name", ["numpy", "jax"])
def test_traced_values_are_never_inspected(name):
    eng = engine(name)
    seen = []

    def f(x):
        seen.append((checks.is_concrete(x), checks.is_traced(x), checks.is_traced([x, 1.0])))
        checks.check_finite_if_concrete("x", x)  # would raise on a concrete NaN
        checks.check_distribution("x", x, 3)  # shape only
        return eng.xp.sum(x * x)

    g = eng.grad(f)(np.array([np.nan, 0.2, 0.3]))
    assert seen[0] == (False, True, True)
    assert np.isnan(np.asarray(g)[0])
    assert checks.is_concrete(np.float32(1)) and checks.is_concrete([1, (2.0, np.ones(2))])
    assert not checks.is_traced(np.ones(2)) and not checks.is_traced("a")


def test_concreteness_by_type_is_the_same_on_every_call():
    """The answers are remembered per type: asking twice (in either order) changes nothing."""
    import jax.numpy as jnp

    from minimanc.autodiff import Box

    cases = [(np.ones(2), True, False), (np.ma.masked_array([1.0]), True, False),
             (2.5, True, False), (3, True, False), (True, True, False),
             (np.float32(1), True, False), (1 + 2j, True, False), ("a", False, False),
             (None, False, False), ({"a": 1.0}, False, False), (Box(np.ones(2)), False, True),
             (jnp.ones(2), False, True), ([1.0, np.ones(2)], True, False),
             ((1.0, Box(1.0)), False, True)]
    for _ in range(2):
        for x, concrete, traced in cases + cases[::-1]:
            assert checks.is_concrete(x) is concrete, x
            assert checks.is_traced(x) is traced, x


# --------------------------------------------------------------------------- distributions


def test_check_distribution_uses_the_precision_of_the_values():
    q32 = np.full(4, 0.25, dtype=np.float32)
    q32[0] -= np.float32(2e-6)  # 2e-6 < 8 · 4 · eps32 = 3.8e-6
    checks.check_distribution("q", q32, 4)
    with pytest.raises(ValueError, match="within float32 precision: if q holds float32"):
        checks.check_distribution("q", q32.astype(np.float64), 4)  # float64: its precision
    q64 = np.full(4, 0.25)
    q64[0] -= 1e-9
    with pytest.raises(ValueError, match=r"q must be a probability distribution: entries sum "
                                         r"to 0\.999999999.*tolerance 7\.11e-15"):
        checks.check_distribution("q", q64, 4)
    with pytest.raises(ValueError, match=r"q must have shape \(\.\.\., N\) with N = 3 states"):
        checks.check_distribution("q", q64, 3)
    with pytest.raises(ValueError, match="negative entry"):
        checks.check_distribution("q", np.array([1.5, -0.5]), 2)
    with pytest.raises(ValueError, match="q must be finite"):
        checks.check_distribution("q", np.array([np.nan, 1.0]), 2)


def test_check_stochastic_columns():
    T = np.array([[0.9, 0.5], [0.1, 0.5]])
    assert np.array_equal(checks.check_stochastic_columns("T", T), T)
    with pytest.raises(ValueError, match=r"T must be finite; got T with 1 non-finite entry "
                                         r"\(first nan\)"):
        checks.check_stochastic_columns("T", np.array([[np.nan, 0.5], [0.1, 0.5]]))
    with pytest.raises(ValueError, match="T must be column-stochastic"):
        checks.check_stochastic_columns("T", T.T)
    with pytest.raises(ValueError, match=r"T must have shape \(\.\.\., N, N\)"):
        checks.check_stochastic_columns("T", np.ones((2, 3)))


# --------------------------------------------------------------------------- shapes


@settings(max_examples=60, deadline=None)
@given(hnp.array_shapes(min_dims=0, max_dims=3, max_side=4),
       hnp.array_shapes(min_dims=0, max_dims=3, max_side=4))
def test_check_broadcast_agrees_with_numpy(a, b):
    x, y = np.zeros(a + (4,)), np.zeros(b)
    try:
        expect = np.broadcast_shapes(a, b)
    except ValueError:
        with pytest.raises(ValueError, match=rf"x with shape {tuple(x.shape)}".replace("(", r"\(")
                           .replace(")", r"\)")):
            checks.check_broadcast(("x", x, 1), ("y", y, 0))
    else:
        assert checks.check_broadcast(("x", x, 1), ("y", y, 0)) == expect


def test_check_leading_axis():
    assert checks.check_leading_axis("g", [1.0, 2.0], 2, "is listed in per_step").shape == (2,)
    x32 = np.ones((3, 2), dtype=np.float32)
    assert checks.check_leading_axis("g", x32, 3, "is per step") is x32  # dtype kept
    with pytest.raises(ValueError, match=r"g is per step, so its leading axis must have "
                                         r"length 4; got g with shape \(3, 2\)"):
        checks.check_leading_axis("g", x32, 4, "is per step")


# --------------------------------------------------------------------------- rng and dtype


def test_check_rng_accepts_a_generator_and_names_anything_else():
    rng = np.random.default_rng(0)
    assert checks.check_rng("rng", rng) is rng
    for bad in (0, None, np.random.RandomState(0)):
        with pytest.raises(ValueError, match=r"gen must be a numpy.random.Generator, got gen="):
            checks.check_rng("gen", bad)


@given(st.sampled_from([np.float16, np.float32, np.float64, "float32", float]))
def test_check_float_dtype_returns_the_dtype(dtype):
    assert checks.check_float_dtype("dtype", dtype) == np.dtype(dtype)


@pytest.mark.parametrize("bad", [np.int32, "int64", bool, np.complex128])
def test_check_float_dtype_refuses_other_types(bad):
    with pytest.raises(ValueError, match="dt must be a floating-point type, got dt="):
        checks.check_float_dtype("dt", bad)
