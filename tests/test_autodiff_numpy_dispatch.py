"""Tests for minimanc.autodiff (chapter 1): a gradient is never dropped silently —
conversions of traced values are refused with what to write instead, and NumPy's own
functions on traced values dispatch to our primitives or raise naming the function."""

from __future__ import annotations

import math

import hypothesis.extra.numpy as hnp
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from autodiff_strategies import SETTINGS, seeds, shapes
from hypothesis import given
from hypothesis import strategies as st

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import (
    Box,
    TracerConversionError,
    check_grads,
    grad,
    stop_gradient,
    value_and_grad,
)
from minimanc.engine import get_engine

get_engine("jax")  # turns on jax_enable_x64


# ---------------------------------------------------------------------------
# A gradient is never dropped silently
# ---------------------------------------------------------------------------
X3 = np.array([0.5, 1.0, 2.0])

CONVERSIONS = {  # name: (function of a traced 1-D x, text the message must contain)
    "float": (lambda x: float(x[0]) * 2, r"float\(x\)"),
    "int": (lambda x: int(x[0]) * 1.0, r"int\(x\).*stop_gradient"),
    "complex": (lambda x: complex(x[0]).real, r"complex\(x\)"),
    "item": (lambda x: x[0].item(), r"x\.item\(\)"),
    "tolist": (lambda x: x.tolist()[0], r"x\.tolist\(\).*x\[i\]"),
    "math.sin": (lambda x: math.sin(x[0]), r"math\.sin.*minimanc\.autodiff\.numpy\.sin"),
    "math.exp": (lambda x: math.exp(x[0]), r"minimanc\.autodiff\.numpy\.exp"),
    "np.float64": (lambda x: np.float64(x[0]), r"np\.float64\(x\).*astype"),
    "np.asarray": (lambda x: np.asarray(x).sum(), r"np\.asarray\(x\).*numpy\.asarray"),
    "np.array": (lambda x: np.array(x).sum(), r"np\.array\(x\)"),
    "np.array of boxes": (lambda x: np.array([x[0], x[1]]).sum(), r"numpy\.stack"),
}


@pytest.mark.parametrize("name", list(CONVERSIONS))
def test_conversion_of_a_traced_value_raises_and_says_what_to_write(name):
    fun, pattern = CONVERSIONS[name]
    with pytest.raises(TracerConversionError, match=pattern) as info:
        grad(fun)(X3)
    msg = str(info.value)
    assert isinstance(info.value, TypeError)
    assert "traced value" in msg and "lose its gradient" in msg and "stop_gradient" in msg


def test_bool_format_and_comparisons_of_traced_values_stay_allowed():
    def f(x):  # control flow on the concrete value: exact gradient of the branch taken
        label = f"{x:.2f}"  # logging inside a traced function
        assert label in ("-1.50", "2.00")
        y = x * 3.0 if x > 0 else x * -2.0
        return y * 2.0 if bool(x) else y

    assert grad(f)(2.0) == 6.0 and grad(f)(-1.5) == -4.0
    np.testing.assert_array_equal(
        grad(lambda x: anp.sum(anp.where(x > 1.0, x * x, 0.0)))(X3), [0.0, 0.0, 4.0])


def test_assignment_of_a_traced_value_into_a_numpy_array_raises():
    def scalar_assign(x):
        y = anp.zeros(3)
        y[0] = x[0]
        return anp.sum(y)

    def slice_assign(x):
        y = anp.zeros(3)
        y[:2] = x[:2]
        return anp.sum(y)

    # NumPy wraps the scalar case in its own ValueError; ours is the direct cause
    with pytest.raises(ValueError) as info:
        grad(scalar_assign)(X3)
    assert isinstance(info.value.__cause__, TracerConversionError)
    assert "y[i] = x into a NumPy array" in str(info.value.__cause__)
    with pytest.raises(TracerConversionError, match=r"y\[i\] = x into a NumPy array"):
        grad(slice_assign)(X3)
    # what to write instead, and it agrees with JAX's .at[].set
    g = grad(lambda x: anp.sum(anp.concatenate([x[:1], anp.zeros(2)]) * X3))(X3)
    ref = jax.grad(lambda x: jnp.sum(jnp.zeros(3).at[0].set(x[0]) * X3))(X3)
    np.testing.assert_array_equal(g, ref)


def test_stop_gradient_is_the_deliberate_conversion():
    def f(x):
        loss = anp.sum(x * stop_gradient(x))
        seen.append(float(stop_gradient(loss)))  # logging a traced loss
        return loss

    seen: list = []
    g = grad(f)(X3)
    ref = jax.grad(lambda x: jnp.sum(x * jax.lax.stop_gradient(x)))(X3)
    np.testing.assert_array_equal(g, ref)
    assert seen == [5.25]
    tree = stop_gradient({"a": Box(np.ones(2)), "b": [Box(np.zeros(1)), 3.0]})
    assert type(tree["a"]) is np.ndarray and type(tree["b"][0]) is np.ndarray
    assert tree["b"][1] == 3.0 and stop_gradient(X3) is X3


@pytest.mark.parametrize("out, pattern", [
    (lambda x: None, r"returned None \(a missing `return`\?\)"),
    (lambda x: (anp.sum(x), anp.sum(x)), r"got a tuple of 2 values; .*has_aux=True"),
    (lambda x: [anp.sum(x)], r"got a list of 1 values"),
    (lambda x: {"loss": anp.sum(x)}, r"scalar output \(shape \(\)\), got dict"),
    (lambda x: x * 2, r"scalar output \(shape \(\)\), got shape \(3,\)"),
    (lambda x: True, r"got bool: a Python bool has no derivative"),
    (lambda x: anp.sum(x) > 0, r"real floating-point output, got bool"),
    (lambda x: 3, r"real floating-point output, got int64"),
])
def test_grad_refuses_outputs_that_are_not_a_float_scalar(out, pattern):
    with pytest.raises(TypeError, match=pattern):
        grad(out)(X3)


def test_grad_has_aux_refuses_a_none_value_and_constant_outputs_have_zero_gradient():
    with pytest.raises(TypeError, match="returned None"):
        grad(lambda x: (None, {}), has_aux=True)(X3)
    np.testing.assert_array_equal(grad(lambda x: 2.0)(X3), np.zeros(3))  # as JAX
    np.testing.assert_array_equal(grad(lambda x: np.float64(2.0))(X3), np.zeros(3))
    np.testing.assert_array_equal(jax.grad(lambda x: 2.0)(X3), np.zeros(3))


A33 = np.arange(9.0).reshape(3, 3) / 4
NUMPY_DISPATCH = {  # name: (f written with NumPy's functions, same with ours)
    "sum": (lambda x: np.sum(np.exp(x)), lambda x: anp.sum(anp.exp(x))),
    "sum axis keepdims": (lambda x: np.sum(np.sum(x[:, None] * A33, 0, keepdims=True) ** 2),
                          lambda x: anp.sum(anp.sum(x[:, None] * A33, 0, keepdims=True) ** 2)),
    "mean": (lambda x: np.mean(np.log(x) * x), lambda x: anp.mean(anp.log(x) * x)),
    "max": (lambda x: np.max(np.sin(x)), lambda x: anp.max(anp.sin(x))),
    "min": (lambda x: np.min(np.tanh(x) - x), lambda x: anp.min(anp.tanh(x) - x)),
    "sqrt abs": (lambda x: np.sum(np.sqrt(np.abs(x))), lambda x: anp.sum(anp.sqrt(anp.abs(x)))),
    "matmul": (lambda x: np.sum(np.matmul(A33, x) ** 2), lambda x: anp.sum((A33 @ x) ** 2)),
    "multiply add": (lambda x: np.sum(np.add(np.multiply(x, x), x)),
                     lambda x: anp.sum(x * x + x)),
    "add.reduce": (lambda x: np.add.reduce(x * x), lambda x: anp.sum(x * x)),
    "var std": (lambda x: np.var(x) + np.std(x, ddof=1), lambda x: anp.var(x) + anp.std(x, ddof=1)),
    "cumsum": (lambda x: np.sum(np.cumsum(x) ** 2), lambda x: anp.sum(anp.cumsum(x) ** 2)),
    "norm": (lambda x: np.linalg.norm(x), lambda x: anp.linalg.norm(x)),
    "where clip": (lambda x: np.sum(np.where(x > 0.7, x, x * x) + np.clip(x, 0.6, 1.5)),
                   lambda x: anp.sum(anp.where(x > 0.7, x, x * x) + anp.clip(x, 0.6, 1.5))),
    "concatenate stack": (
        lambda x: np.sum(np.concatenate([x, x * x]) * np.stack([x, x], axis=1).ravel()),
        lambda x: anp.sum(anp.concatenate([x, x * x]) * anp.stack([x, x], axis=1).ravel())),
    "einsum dot": (lambda x: np.einsum("i,ij,j->", x, A33, x) + np.dot(x, x),
                   lambda x: anp.einsum("i,ij,j->", x, A33, x) + anp.dot(x, x)),
    "reshape transpose": (lambda x: np.sum(np.transpose(np.reshape(x, (3, 1))) @ A33),
                          lambda x: anp.sum(anp.transpose(anp.reshape(x, (3, 1))) @ A33)),
    "cross pad": (lambda x: np.sum(np.cross(x, A33[0] + 1) * np.pad(x, 1)[1:-1]),
                  lambda x: anp.sum(anp.cross(x, A33[0] + 1) * anp.pad(x, 1)[1:-1])),
    "maximum power": (lambda x: np.sum(np.maximum(x, 1.0) ** np.power(x, 2.0)),
                      lambda x: anp.sum(anp.maximum(x, 1.0) ** anp.power(x, 2.0))),
}


@pytest.mark.parametrize("name", list(NUMPY_DISPATCH))
def test_numpy_functions_on_traced_values_dispatch_to_our_primitives(name):
    np_version, ours = NUMPY_DISPATCH[name]
    value, g = value_and_grad(np_version)(X3)
    ref_value, ref = value_and_grad(ours)(X3)
    np.testing.assert_allclose(value, np_version(X3), rtol=1e-12)
    np.testing.assert_allclose(value, ref_value, rtol=1e-12)
    np.testing.assert_allclose(g, ref, rtol=1e-12)
    check_grads(np_version, X3, verbose=False)


def test_plain_numpy_helpers_on_traced_values_return_plain_values():
    def f(x):
        assert np.shape(x) == (3,) and np.ndim(x) == 1 and np.size(x) == 3
        assert np.result_type(x) == np.float64
        for plain in (np.zeros_like(x), np.isfinite(x), np.sign(x), np.argmax(x), np.round(x),
                      np.allclose(x, x), np.floor(x), np.ones(3) < x, np.equal(x, x)):
            assert not isinstance(plain, Box)
        assert np.all(np.isfinite(x)) and bool(np.argmax(x) == 2)
        return np.sum(x * np.ones_like(x))

    np.testing.assert_array_equal(grad(f)(X3), np.ones(3))


def test_ndarray_on_the_left_of_an_operator_gives_boxes():
    kinds = {}

    def f(x):
        terms = {"mul": np.ones(3) * x, "matmul": np.ones(3) @ x, "sub": np.ones(3) - x,
                 "div": np.ones(3) / x, "pow": np.full(3, 2.0) ** x, "mod": np.ones(3) % x,
                 "scalar": np.float64(2.0) * x, "scalar32": np.float32(2.0) - x,
                 "matrix": A33 @ x}
        kinds.update({k: type(v) for k, v in terms.items()})
        kinds["lt"], kinds["eq"] = type(np.ones(3) < x), type(np.ones(3) == x)
        return anp.sum(anp.stack([anp.sum(v) for v in terms.values()]))

    g = grad(f)(X3)
    assert all(kinds[k] is Box for k in kinds if k not in ("lt", "eq"))
    assert kinds["lt"] is np.ndarray and kinds["eq"] is np.ndarray
    ref = jax.grad(lambda x: jnp.sum(jnp.ones(3) * x) + jnp.ones(3) @ x + jnp.sum(1 - x)
                   + jnp.sum(1 / x) + jnp.sum(2.0 ** x) + jnp.sum(jnp.ones(3) % x)
                   + jnp.sum(2.0 * x) + jnp.sum(2.0 - x) + jnp.sum(A33 @ x))(X3)
    np.testing.assert_allclose(g, ref, rtol=1e-12)


@pytest.mark.parametrize("call, pattern", [
    (lambda x: np.prod(x), r"^np\.prod has no derivative in minimanc\.autodiff: use "
                           r"minimanc\.autodiff\.numpy \(anp\): anp\.exp\(anp\.sum\(anp\.log"),
    (lambda x: np.linalg.svd(x[:, None] * A33)[1].sum(),
     r"^np\.linalg\.svd has no derivative in minimanc\.autodiff: .*write the primitive"),
    (lambda x: np.sum(np.hypot(x, x)), r"^np\.hypot has no derivative.*anp\.sqrt"),
    (lambda x: np.sum(np.multiply.outer(x, x)), r"^np\.multiply\.outer has no derivative"),
    (lambda x: np.sum(np.cumprod(x)), r"^np\.cumprod has no derivative"),
])
def test_numpy_functions_without_a_primitive_raise(call, pattern):
    with pytest.raises(TypeError, match=pattern):
        grad(call)(X3)


@pytest.mark.parametrize("call", [
    lambda x: np.sum(np.exp(x, out=np.empty(3))),
    lambda x: np.sum(x, out=np.empty(())),
    lambda x: np.sum(np.add(np.zeros(3), x, out=np.zeros(3))),
    lambda x: anp.sum(np.zeros(3).__iadd__(x)),
    lambda x: np.add.at(np.zeros(3), [0], x),
])
def test_in_place_numpy_writes_of_traced_values_are_refused(call):
    with pytest.raises(TypeError, match=r"in place, which cannot be traced: build a new array"):
        grad(call)(X3)


def test_numpy_options_we_do_not_support_are_refused_by_name():
    with pytest.raises(TypeError, match=r"np\.sum\(\.\.\., initial=\.\.\.\) is not supported"):
        grad(lambda x: np.sum(x, initial=1.0))(X3)
    with pytest.raises(TypeError, match=r"np\.exp\(\.\.\., where=\.\.\.\) is not supported"):
        grad(lambda x: np.sum(np.exp(x, where=x > 1)))(X3)
    with pytest.raises(TypeError, match=r"np\.cross\(\.\.\., axisa=\.\.\.\) is not supported"):
        grad(lambda x: np.sum(np.cross(x, x, axisa=0)))(X3)
    # options at their default values are accepted
    g = grad(lambda x: np.sum(np.reshape(x, (3,), order="C"), axis=None, out=None))(X3)
    np.testing.assert_array_equal(g, np.ones(3))


@SETTINGS
# distinct, normal floats: a tie in max splits its gradient, and XLA flushes subnormal
# results to zero (sin(1e-308) == 0 there), which turns distinct entries into a tie
@given(x=hnp.arrays(np.float64, shapes, elements=st.floats(-2, 2, allow_subnormal=False),
                    unique=True), seed=seeds)
def test_numpy_functions_give_our_gradient_and_jax_s(x, seed):
    w = np.random.default_rng(seed).normal(size=x.shape)

    def numpy_version(x):
        return np.sum(np.exp(x) * w) + np.mean(w * np.tanh(x)) + np.max(np.sin(x))

    def ours(x):
        return anp.sum(anp.exp(x) * w) + anp.mean(w * anp.tanh(x)) + anp.max(anp.sin(x))

    g = grad(numpy_version)(x)
    assert isinstance(g, np.ndarray) and g.shape == x.shape and g.dtype == np.float64
    np.testing.assert_array_equal(g, grad(ours)(x))
    ref = jax.grad(lambda x: jnp.sum(jnp.exp(x) * w) + jnp.mean(w * jnp.tanh(x))
                   + jnp.max(jnp.sin(x)))(x)
    np.testing.assert_allclose(g, np.asarray(ref), rtol=1e-9, atol=1e-12)


def test_stack_is_one_traced_operation_and_expand_dims_accepts_every_axis():
    seen = []

    def f(x):
        s = anp.stack([x, 2.0 * x, np.ones(3)], axis=-1)  # traced, traced, plain
        seen.append(s)
        return anp.sum(s * np.arange(9.0).reshape(3, 3))

    g = grad(f)(np.ones(3))
    np.testing.assert_allclose(g, np.arange(9.0).reshape(3, 3)[:, 0]
                               + 2.0 * np.arange(9.0).reshape(3, 3)[:, 1])
    assert seen[0].primitive_name == "stack"
    assert [p.primitive_name for _, p in seen[0].parents] == [None, "multiply"]
    x = np.zeros((2, 3))
    for axis in (-3, -2, -1, 0, 1, 2):
        assert anp.expand_dims(x, axis).shape == np.expand_dims(x, axis).shape
    with pytest.raises(ValueError, match="expand_dims"):
        grad(lambda v: anp.sum(anp.expand_dims(v, 3)))(x)

