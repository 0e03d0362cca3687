"""Tests for minimanc.autodiff (chapter 1): every primitive against central
differences and against ``jax.grad`` (float64), plus regression tests for the
classic bugs of small autodiff engines."""

from __future__ import annotations

import math
import sys
from collections import namedtuple

import hypothesis.extra.numpy as hnp
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import (
    Box,
    TracerConversionError,
    check_grads,
    defvjp,
    defvjp_fwd,
    grad,
    primitive,
    stop_gradient,
    unbroadcast,
    value_and_grad,
)
from minimanc.engine import get_engine

get_engine("jax")  # turns on jax_enable_x64

SETTINGS = settings(max_examples=25, deadline=None)
seeds = st.integers(0, 2**32 - 1)
shapes = hnp.array_shapes(min_dims=0, max_dims=3, min_side=1, max_side=3)
pairs = hnp.mutually_broadcastable_shapes(num_shapes=2, min_dims=0, max_dims=3, max_side=3)


def _sample(rng, shape, domain):
    lo, hi = domain
    x = rng.uniform(lo, hi, size=shape)
    return np.asarray(x, dtype=np.float64)


def _weighted(xp, op, w):
    return lambda *a: xp.sum(op(xp, *a) * w)


def assert_grads_ok(op, *args, rng, against_jax=False):
    """Gradient of ``sum(op(xp, *args) * W)`` (random W) equals central differences,
    and ``jax.grad``'s (float64, rtol 1e-6) when ``against_jax``."""
    plain = op(np, *args)
    ours_plain = op(anp, *args)
    assert not isinstance(ours_plain, Box)
    np.testing.assert_allclose(ours_plain, plain, rtol=1e-12, atol=1e-12)
    w = rng.normal(size=np.shape(plain))
    nums = tuple(range(len(args)))
    ours = grad(_weighted(anp, op, w), argnums=nums)(*args)
    for a, g in zip(args, ours):
        assert isinstance(g, np.ndarray) and g.shape == np.shape(a) and g.dtype == np.float64
    if against_jax:
        ref = jax.grad(_weighted(jnp, op, w), argnums=nums)(*args)
        for g, r in zip(ours, ref):
            np.testing.assert_allclose(g, np.asarray(r), rtol=1e-6, atol=1e-9)
    else:
        check_grads(_weighted(anp, op, w), *args, verbose=False)


# ---------------------------------------------------------------------------
# Element-wise primitives
# ---------------------------------------------------------------------------
UNARY = {
    "negative": (lambda xp, x: xp.negative(x), (-2, 2)),
    "unary minus": (lambda xp, x: -x, (-2, 2)),
    "exp": (lambda xp, x: xp.exp(x), (-2, 2)),
    "log": (lambda xp, x: xp.log(x), (0.3, 3)),
    "sqrt": (lambda xp, x: xp.sqrt(x), (0.3, 3)),
    "abs": (lambda xp, x: xp.abs(x), (-2, 2)),
    "tanh": (lambda xp, x: xp.tanh(x), (-2, 2)),
    "sin": (lambda xp, x: xp.sin(x), (-3, 3)),
    "cos": (lambda xp, x: xp.cos(x), (-3, 3)),
    "arccos": (lambda xp, x: xp.arccos(x), (-0.9, 0.9)),
    "arcsin": (lambda xp, x: xp.arcsin(x), (-0.9, 0.9)),
    "arctan": (lambda xp, x: xp.arctan(x), (-2, 2)),
    "square": (lambda xp, x: xp.square(x), (-2, 2)),
    "log1p": (lambda xp, x: xp.log1p(x), (-0.5, 2)),
    "expm1": (lambda xp, x: xp.expm1(x), (-2, 2)),
    "x ** 2": (lambda xp, x: x**2, (-2, 2)),
    "x ** 0.5": (lambda xp, x: x**0.5, (0.3, 2)),
    "2 ** x": (lambda xp, x: 2**x, (-2, 2)),
    "1 - x": (lambda xp, x: 1 - x, (-2, 2)),
    "2 * x / 3": (lambda xp, x: 2 * x / 3, (-2, 2)),
    "1 / x": (lambda xp, x: 1 / x, (0.5, 2)),
    "clip": (lambda xp, x: xp.clip(x, -0.5, 0.7), (-2, 2)),
    "astype": (lambda xp, x: x.astype(xp.float32).astype(xp.float64) * 0 + x, (-2, 2)),
}


@pytest.mark.parametrize("name", sorted(UNARY))
@SETTINGS
@given(shape=shapes, seed=seeds)
def test_unary_primitives(name, shape, seed):
    op, domain = UNARY[name]
    rng = np.random.default_rng(seed)
    assert_grads_ok(op, _sample(rng, shape, domain), rng=rng)


BINARY = {
    "add": (lambda xp, x, y: xp.add(x, y), (-2, 2), (-2, 2)),
    "subtract": (lambda xp, x, y: xp.subtract(x, y), (-2, 2), (-2, 2)),
    "multiply": (lambda xp, x, y: xp.multiply(x, y), (-2, 2), (-2, 2)),
    "divide": (lambda xp, x, y: xp.divide(x, y), (-2, 2), (0.5, 2)),
    "power": (lambda xp, x, y: xp.power(x, y), (0.5, 2), (-2, 2)),
    "operators": (lambda xp, x, y: (x + y) * x - y / (1 + x * x) + x**y, (0.5, 2), (-1, 1)),
    "maximum": (lambda xp, x, y: xp.maximum(x, y), (-2, 2), (-2, 2)),
    "minimum": (lambda xp, x, y: xp.minimum(x, y), (-2, 2), (-2, 2)),
    "arctan2": (lambda xp, x, y: xp.arctan2(x, y), (-2, 2), (0.5, 2)),
    "where": (lambda xp, x, y: xp.where(x > 0, x * 2, y**2), (-2, 2), (-2, 2)),
    "remainder": (lambda xp, x, y: x % y + xp.mod(y, 0.7), (-3, 3), (0.6, 1.5)),
    "logaddexp": (lambda xp, x, y: xp.logaddexp(x, y), (-3, 3), (-3, 3)),
}


@pytest.mark.parametrize("name", sorted(BINARY))
@SETTINGS
@given(shapes2=pairs, seed=seeds)
def test_binary_primitives_broadcasting(name, shapes2, seed):
    op, dx, dy = BINARY[name]
    (sx, sy), _ = shapes2
    rng = np.random.default_rng(seed)
    assert_grads_ok(op, _sample(rng, sx, dx), _sample(rng, sy, dy), rng=rng)


# ---------------------------------------------------------------------------
# Reductions
# ---------------------------------------------------------------------------
@st.composite
def shape_and_axis(draw, min_dims=1):
    shape = draw(hnp.array_shapes(min_dims=min_dims, max_dims=3, min_side=1, max_side=4))
    kind = draw(st.sampled_from(["none", "int", "tuple"]))
    if kind == "none":
        return shape, None
    if kind == "int":
        return shape, draw(st.integers(-len(shape), len(shape) - 1))
    axes = draw(st.lists(st.integers(0, len(shape) - 1), min_size=1, max_size=len(shape),
                         unique=True))
    return shape, tuple(axes)


REDUCTIONS = {
    "sum": lambda xp, x, axis, kd: xp.sum(x, axis=axis, keepdims=kd),
    "mean": lambda xp, x, axis, kd: xp.mean(x, axis=axis, keepdims=kd),
    "max": lambda xp, x, axis, kd: xp.max(x, axis=axis, keepdims=kd),
    "min": lambda xp, x, axis, kd: xp.min(x, axis=axis, keepdims=kd),
    "method sum": lambda xp, x, axis, kd: x.sum(axis=axis, keepdims=kd),
    "method mean": lambda xp, x, axis, kd: x.mean(axis=axis, keepdims=kd),
    "var": lambda xp, x, axis, kd: xp.var(x, axis=axis, keepdims=kd),
    "norm": lambda xp, x, axis, kd: xp.linalg.norm(
        x, axis=axis if not isinstance(axis, tuple) or len(axis) <= 2 else None, keepdims=kd
    ),
}


@pytest.mark.parametrize("name", sorted(REDUCTIONS))
@SETTINGS
@given(sa=shape_and_axis(), keepdims=st.booleans(), seed=seeds)
def test_reductions(name, sa, keepdims, seed):
    shape, axis = sa
    if name == "norm" and isinstance(axis, tuple) and len(axis) == 1:
        axis = axis[0]
    rng = np.random.default_rng(seed)
    x = _sample(rng, shape, (-2, 2))
    op = REDUCTIONS[name]
    assert_grads_ok(lambda xp, x: op(xp, x, axis, keepdims), x, rng=rng)


def test_max_ties_share_the_gradient_like_jax():
    x = np.array([[1.0, 3.0, 3.0], [2.0, 2.0, 2.0]])
    ours = grad(lambda x: anp.sum(anp.max(x, axis=1)))(x)
    ref = jax.grad(lambda x: jnp.sum(jnp.max(x, axis=1)))(x)
    np.testing.assert_allclose(ours, ref)
    np.testing.assert_allclose(ours, [[0, 0.5, 0.5], [1 / 3, 1 / 3, 1 / 3]])
    g = grad(lambda x: anp.sum(anp.maximum(x, 0.0)))(np.array([-1.0, 0.0, 1.0]))
    np.testing.assert_allclose(g, jax.grad(lambda x: jnp.sum(jnp.maximum(x, 0.0)))(
        np.array([-1.0, 0.0, 1.0])))


# ---------------------------------------------------------------------------
# Linear algebra
# ---------------------------------------------------------------------------
@st.composite
def matmul_shapes(draw):
    n, k, m = (draw(st.integers(1, 4)) for _ in range(3))
    batch = draw(hnp.mutually_broadcastable_shapes(num_shapes=2, max_dims=2, max_side=3))
    (bx, by), _ = batch
    kind = draw(st.sampled_from(["mm", "vm", "mv", "vv", "batched"]))
    if kind == "mm":
        return (n, k), (k, m)
    if kind == "vm":
        return (k,), bx + (k, m)
    if kind == "mv":
        return bx + (n, k), (k,)
    if kind == "vv":
        return (k,), (k,)
    return bx + (n, k), by + (k, m)


@SETTINGS
@given(sh=matmul_shapes(), seed=seeds)
def test_matmul(sh, seed):
    rng = np.random.default_rng(seed)
    x, y = _sample(rng, sh[0], (-1, 1)), _sample(rng, sh[1], (-1, 1))
    assert_grads_ok(lambda xp, x, y: x @ y, x, y, rng=rng)


DOT_SHAPES = [((), (3,)), ((3,), ()), ((3,), (3,)), ((2, 3), (3,)), ((3,), (3, 2)),
              ((2, 3), (3, 4)), ((2, 2, 3), (3,)), ((2, 3), (4, 3, 2)), ((2, 2, 3), (2, 3, 2))]


@pytest.mark.parametrize("sx,sy", DOT_SHAPES)
def test_dot(sx, sy):
    rng = np.random.default_rng(1)
    x, y = _sample(rng, sx, (-1, 1)), _sample(rng, sy, (-1, 1))
    assert_grads_ok(lambda xp, x, y: xp.dot(x, y), x, y, rng=rng)


EINSUMS = ["ij,jk->ik", "ij,jk", "bij,bjk->bik", "...ij,...jk->...ik", "i,i->", "ij->j",
           "ij", "ij,j->i", "ijk,ikl,lm->jm", "ij,kl->ijkl", "ij,ik->i", "ij,jk,kl->il",
           "bhw,hwc->bc"]


@pytest.mark.parametrize("spec", EINSUMS)
@settings(max_examples=10, deadline=None)
@given(seed=seeds, extra=st.integers(0, 2))
def test_einsum(spec, seed, extra):
    rng = np.random.default_rng(seed)
    sizes = {c: int(rng.integers(1, 4)) for c in "abcdefghijklmnopqrstuvwxyz"}
    lhs = spec.split("->")[0].split(",")
    ops = []
    for t in lhs:
        ell = tuple(int(s) for s in rng.integers(1, 3, size=extra)) if "..." in t else ()
        ops.append(_sample(rng, ell + tuple(sizes[c] for c in t.replace("...", "")), (-1, 1)))
    assert_grads_ok(lambda xp, *a: xp.einsum(spec, *a), *ops, rng=rng)


@SETTINGS
@given(shapes2=hnp.mutually_broadcastable_shapes(num_shapes=2, base_shape=(3,), max_dims=3,
                                                 max_side=3), seed=seeds)
def test_cross(shapes2, seed):
    (sa, sb), _ = shapes2
    if sa[-1:] != (3,) or sb[-1:] != (3,):
        sa, sb = sa[:-1] + (3,) if sa else (3,), sb[:-1] + (3,) if sb else (3,)
    rng = np.random.default_rng(seed)
    a, b = _sample(rng, sa, (-1, 1)), _sample(rng, sb, (-1, 1))
    assert_grads_ok(lambda xp, a, b: xp.cross(a, b), a, b, rng=rng)


# ---------------------------------------------------------------------------
# Shapes, indexing, joining
# ---------------------------------------------------------------------------
SHAPE_OPS = {
    "reshape": lambda xp, x: xp.reshape(x, (-1,)),
    "method reshape": lambda xp, x: x.reshape(x.size, 1),
    "transpose": lambda xp, x: xp.transpose(x),
    "transpose axes": lambda xp, x: xp.transpose(x, tuple(range(x.ndim))[::-1]),
    ".T": lambda xp, x: x.T * xp.arange(1.0, 1.0 + x.T.shape[-1] if x.ndim else 2.0)[-1],
    "swapaxes": lambda xp, x: xp.swapaxes(x, 0, -1),
    "expand_dims": lambda xp, x: xp.expand_dims(x, 1),
    "squeeze": lambda xp, x: xp.squeeze(xp.expand_dims(x, 0), 0),
    "concatenate": lambda xp, x: xp.concatenate([x, 2 * x, x * x], axis=-1),
    "stack": lambda xp, x: xp.stack([x, x * x], axis=1),
    "stack -1": lambda xp, x: xp.stack([x, x * x, -x], axis=-1),
    "slice": lambda xp, x: x[1:, ::2],
    "int index": lambda xp, x: x[-1],
    "fancy repeat": lambda xp, x: x[np.array([0, 0, 1, 0])],
    "fancy 2d": lambda xp, x: x[np.array([0, 1, 1]), np.array([1, 0, 1])],
    "bool mask": lambda xp, x: x[x > 0],
    "newaxis ellipsis": lambda xp, x: x[..., xp.newaxis, 0],
}


@pytest.mark.parametrize("name", sorted(SHAPE_OPS))
@SETTINGS
@given(shape=hnp.array_shapes(min_dims=2, max_dims=3, min_side=2, max_side=3), seed=seeds)
def test_shape_ops_and_indexing(name, shape, seed):
    rng = np.random.default_rng(seed)
    x = _sample(rng, shape, (-2, 2))
    assert_grads_ok(SHAPE_OPS[name], x, rng=rng)


# ---------------------------------------------------------------------------
# Every primitive against jax.grad (fixed shapes: JAX compiles per shape, so
# random shapes would cost seconds each; the random shapes are covered above
# against central differences)
# ---------------------------------------------------------------------------
def _jax_cases():
    cases = {}
    for n, (op, dom) in UNARY.items():
        cases[f"unary {n}"] = (op, [((2, 3), dom)])
    for n, (op, dx, dy) in BINARY.items():
        cases[f"broadcast {n} (2,1)x(3,)"] = (op, [((2, 1), dx), ((3,), dy)])
        cases[f"broadcast {n} ()x(2,3)"] = (op, [((), dx), ((2, 3), dy)])
    for n, op in REDUCTIONS.items():
        for axis, kd in ((None, False), (1, False), ((0, 2), True)):
            cases[f"reduce {n} axis={axis} keepdims={kd}"] = (
                lambda xp, x, op=op, axis=axis, kd=kd: op(xp, x, axis, kd), [((2, 3, 2), (-2, 2))])
    for sx, sy in (((2, 3), (3, 4)), ((3,), (3, 2)), ((2, 3), (3,)), ((3,), (3,)),
                   ((2, 1, 2, 3), (4, 3, 2))):
        cases[f"matmul {sx}@{sy}"] = (lambda xp, x, y: x @ y, [(sx, (-1, 1)), (sy, (-1, 1))])
    for spec in EINSUMS:
        lhs = spec.split("->")[0].split(",")
        cases[f"einsum {spec}"] = (
            lambda xp, *a, spec=spec: xp.einsum(spec, *a),
            [(tuple(2 + "ijklmbhwc".find(c) % 2 for c in t.replace("...", "a")), (-1, 1))
             for t in lhs])
    for sx, sy in DOT_SHAPES:
        cases[f"dot {sx}.{sy}"] = (lambda xp, x, y: xp.dot(x, y), [(sx, (-1, 1)), (sy, (-1, 1))])
    cases["cross"] = (lambda xp, a, b: xp.cross(a, b), [((2, 3), (-1, 1)), ((3,), (-1, 1))])
    for n, op in SHAPE_OPS.items():
        cases[f"shape {n}"] = (op, [((2, 3, 2), (-2, 2))])
    return cases


JAX_CASES = _jax_cases()
EAGER_ONLY = {"shape bool mask"}  # data-dependent shape: cannot be traced by jax.jit


@pytest.fixture(scope="module")
def jax_reference():
    """Inputs, weights and jax.grad for every case, computed in one jitted call."""
    rng = np.random.default_rng(7)
    data = {}
    for name, (op, specs) in JAX_CASES.items():
        args = [_sample(rng, shape, dom) for shape, dom in specs]
        data[name] = (args, rng.normal(size=np.shape(op(np, *args))))
    batched = [n for n in data if n not in EAGER_ONLY]

    def total(all_args):
        return sum(jnp.sum(JAX_CASES[n][0](jnp, *all_args[n]) * data[n][1]) for n in batched)

    refs = jax.jit(jax.grad(total))({n: data[n][0] for n in batched})
    for n in EAGER_ONLY:
        op, (args, w) = JAX_CASES[n][0], data[n]
        refs[n] = jax.grad(_weighted(jnp, op, w), argnums=tuple(range(len(args))))(*args)
    return data, refs


@pytest.mark.parametrize("name", list(JAX_CASES))
def test_against_jax_grad(name, jax_reference):
    data, refs = jax_reference
    op = JAX_CASES[name][0]
    args, w = data[name]
    np.testing.assert_allclose(op(anp, *args), op(np, *args), rtol=1e-12, atol=1e-12)
    ours = grad(_weighted(anp, op, w), argnums=tuple(range(len(args))))(*args)
    assert len(ours) == len(refs[name])
    for g, r in zip(ours, refs[name]):
        assert g.dtype == np.float64
        np.testing.assert_allclose(g, np.asarray(r), rtol=1e-6, atol=1e-9)


def test_fancy_index_scatter_adds_repeats():
    g = grad(lambda x: anp.sum(x[np.array([2, 2, 0, 2])] * np.array([1.0, 2.0, 3.0, 4.0])))(
        np.zeros(4))
    np.testing.assert_array_equal(g, [3.0, 0.0, 7.0, 0.0])


def test_plain_inputs_give_plain_outputs():
    x = np.arange(6.0).reshape(2, 3)
    for out in (anp.sum(x), anp.exp(x), x @ anp.transpose(x), anp.einsum("ij->i", x),
                anp.concatenate([x, x]), anp.stack([x, x]), anp.linalg.norm(x), anp.max(x, 0),
                anp.where(x > 1, x, 0.0), anp.asarray([1.0, 2.0]), anp.zeros(3)):
        assert isinstance(out, np.ndarray | np.generic)
    assert anp.add(1.0, 2.0) == 3.0


def test_numpy_on_the_left_defers_to_the_box():
    def f(x):
        return anp.sum(np.ones(3) * x + np.float64(2.0) * x + np.arange(3.0) / (1 + x)) + anp.sum(
            np.arange(6.0).reshape(2, 3) @ x)

    x = np.array([0.5, 1.0, 2.0])
    expected = 1 + 2 - np.arange(3.0) / (1 + x) ** 2 + np.arange(6.0).reshape(2, 3).sum(0)
    np.testing.assert_allclose(grad(f)(x), expected, rtol=1e-12)


def test_box_attributes_and_comparisons():
    seen = {}

    def f(x):
        seen.update(shape=x.shape, ndim=x.ndim, dtype=x.dtype, size=x.size, len=len(x),
                    Tshape=x.T.shape, gt=x > 1.0, eq=x == x, rows=[r.shape for r in x])
        return (x.sum() + x.mean() + x.max() + x.min()).astype(np.float64)

    grad(f)(np.arange(6.0).reshape(2, 3))
    assert seen["shape"] == (2, 3) and seen["ndim"] == 2 and seen["dtype"] == np.float64
    assert seen["size"] == 6 and seen["len"] == 2 and seen["Tshape"] == (3, 2)
    assert type(seen["gt"]) is np.ndarray and seen["gt"].dtype == bool and seen["eq"].all()
    assert seen["rows"] == [(3,), (3,)]


def test_non_differentiable_helpers_pass_values_through():
    def f(x):
        z = anp.zeros_like(x) + anp.ones_like(x) + anp.eye(2)[0] + anp.zeros(2) + anp.ones(2)
        assert not isinstance(anp.sign(x), Box) and not isinstance(anp.isfinite(x), Box)
        assert bool(anp.all(anp.isfinite(x))) and not bool(anp.any(x > 10))
        return anp.sum(x * z * anp.asarray(2.0, dtype=anp.float64)) * anp.pi

    np.testing.assert_allclose(grad(f)(np.array([1.0, 2.0])), [6 * np.pi, 4 * np.pi])


def test_asarray_of_a_list_of_boxes_stacks():
    g = grad(lambda a: anp.sum(anp.asarray([a[0] * a[1], a[1], 3.0]) * np.array([1, 2, 3.0])))(
        np.array([2.0, 5.0]))
    np.testing.assert_allclose(g, [5.0, 4.0])


# ---------------------------------------------------------------------------
# grad / value_and_grad semantics and regressions
# ---------------------------------------------------------------------------
def test_node_used_twice():
    np.testing.assert_allclose(grad(lambda x: anp.sum(x * x))(np.array([1.0, -3.0])), [2, -6])
    np.testing.assert_allclose(grad(lambda x: anp.sum(x + x + x))(np.array([1.0])), [3.0])

    def diamond(x):
        a = anp.sin(x)
        return anp.sum(a * anp.exp(a) + a)

    x = np.array([0.3, -0.7])
    np.testing.assert_allclose(grad(diamond)(x), jax.grad(
        lambda x: jnp.sum(jnp.sin(x) * jnp.exp(jnp.sin(x)) + jnp.sin(x)))(x), rtol=1e-12)


def test_gradient_function_called_twice_gives_the_same_result():
    df = grad(lambda x: anp.sum(anp.tanh(x) ** 2))
    x = np.array([0.1, 0.2, 0.3])
    first, second = df(x), df(x)
    np.testing.assert_array_equal(first, second)
    np.testing.assert_allclose(df(2 * x), jax.grad(lambda x: jnp.sum(jnp.tanh(x) ** 2))(2 * x))


def test_broadcasting_in_both_operands():
    x, y = np.arange(3.0).reshape(3, 1), np.arange(4.0).reshape(1, 4) + 1
    gx, gy = grad(lambda x, y: anp.sum(x * y), argnums=(0, 1))(x, y)
    np.testing.assert_allclose(gx, np.full((3, 1), 10.0))
    np.testing.assert_allclose(gy, np.full((1, 4), 3.0))


def test_deep_chain_does_not_hit_the_recursion_limit():
    n = 10_000
    assert n > sys.getrecursionlimit()

    def chain(x):
        for _ in range(n):
            x = x * 1.0001 + 0.0
        return anp.sum(x)

    g = grad(chain)(np.ones(2))
    np.testing.assert_allclose(g, np.full(2, 1.0001**n), rtol=1e-9)


def test_integer_inputs_raise_a_clear_error():
    with pytest.raises(TypeError, match="grad requires real floating-point inputs, got int64 "
                                        "for argument 0"):
        grad(lambda x: anp.sum(x * 1.0))(np.arange(3))
    with pytest.raises(TypeError, match="got int for argument 1"):
        grad(lambda x, y: x * y, argnums=1)(1.0, 2)
    with pytest.raises(TypeError, match=r"argument 0 at \['b'\]"):
        grad(lambda p: p["a"] * 1.0)({"a": 1.0, "b": np.arange(2)})


def test_non_scalar_output_raises():
    with pytest.raises(TypeError, match=r"scalar output.*shape \(3,\)"):
        grad(lambda x: x * 2)(np.ones(3))


def test_mismatched_shapes_name_the_operation_and_shapes():
    with pytest.raises(ValueError, match=r"^matmul: shapes \(3, 4\) and \(5, 2\) are not aligned"):
        grad(lambda a, b: anp.sum(a @ b))(np.ones((3, 4)), np.ones((5, 2)))
    with pytest.raises(ValueError, match=r"^matmul: shapes \(3, 4\) and \(5, 2\) are not aligned"):
        anp.matmul(np.ones((3, 4)), np.ones((5, 2)))
    with pytest.raises(ValueError, match=r"^add: .*\(3,\).*\(4,\)"):
        grad(lambda a: anp.sum(a + np.ones(4)))(np.ones(3))
    with pytest.raises(ValueError, match=r"^dot: shapes \(2, 3\) and \(2,\) are not aligned"):
        anp.dot(np.ones((2, 3)), np.ones(2))


Params = namedtuple("Params", ["w", "b"])


def test_pytrees_and_argnums():
    rng = np.random.default_rng(0)
    params = {"layers": [Params(rng.normal(size=(3, 2)), rng.normal(size=2)),
                         Params(rng.normal(size=(2, 1)), None)],
              "scale": 1.5}
    x = rng.normal(size=(4, 3))

    def model(xp, params, x):
        h = xp.tanh(x @ params["layers"][0].w + params["layers"][0].b)
        return xp.sum((h @ params["layers"][1].w) ** 2) * params["scale"]

    g = grad(lambda p, x: model(anp, p, x))(params, x)
    ref = jax.grad(lambda p, x: model(jnp, p, x))(params, x)
    assert isinstance(g["layers"][0], Params) and g["layers"][1].b is None
    assert isinstance(g["scale"], float)
    for a, b in zip(jax.tree_util.tree_leaves(g), jax.tree_util.tree_leaves(ref)):
        np.testing.assert_allclose(a, b, rtol=1e-10)

    gp, gx = grad(lambda p, x: model(anp, p, x), argnums=(0, 1))(params, x)
    rp, rx = jax.grad(lambda p, x: model(jnp, p, x), argnums=(0, 1))(params, x)
    np.testing.assert_allclose(gx, rx, rtol=1e-10)
    np.testing.assert_allclose(gp["layers"][1].w, rp["layers"][1].w, rtol=1e-10)
    assert isinstance(grad(lambda p, x: model(anp, p, x), argnums=(1,))(params, x), tuple)

    val, (gp2, gx2) = value_and_grad(lambda p, x: model(anp, p, x), argnums=(0, 1))(params, x)
    np.testing.assert_allclose(val, model(np, params, x), rtol=1e-14)
    np.testing.assert_array_equal(gx2, gx)


def test_value_and_grad_has_aux_and_unused_arguments():
    def f(x, y):
        return anp.sum(x**2), {"x2": x * 2}

    (val, aux), g = value_and_grad(f, has_aux=True)(np.array([1.0, 2.0]), 3.0)
    assert float(val) == 5.0 and not isinstance(aux["x2"], Box)
    np.testing.assert_array_equal(aux["x2"], [2.0, 4.0])
    g2, aux2 = grad(f, has_aux=True)(np.array([1.0, 2.0]), 3.0)
    np.testing.assert_array_equal(g, g2)
    gy = grad(lambda x, y: anp.sum(x), argnums=1)(np.ones(2), np.ones((2, 2)))
    np.testing.assert_array_equal(gy, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="argnums"):
        grad(lambda x: x, argnums=3)(1.0)
    with pytest.raises(ValueError, match="argnums=.*twice"):
        grad(lambda x, y: x * y, argnums=(1, -1))(1.0, 2.0)
    assert grad(lambda x, y: x * y, argnums=-1)(3.0, 2.0) == 3.0


def test_determinism_bit_identical():
    rng = np.random.default_rng(3)
    w = {"a": rng.normal(size=(16, 16)), "b": rng.normal(size=16)}
    x = rng.normal(size=(32, 16))

    def loss(w):
        h = x
        for _ in range(5):  # every layer re-uses w: cotangents are summed many times
            h = anp.tanh(h @ w["a"] + w["b"]) + 0.1 * h
        return anp.mean(h**2) + anp.sum(w["a"] * w["a"]) * 1e-3

    g1, g2 = grad(loss)(w), grad(loss)(w)
    for k in w:
        assert g1[k].tobytes() == g2[k].tobytes()


def test_float32_stays_float32():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(3, 2)).astype(np.float32)
    x = rng.normal(size=(5, 3)).astype(np.float32)

    def loss(w):
        h = anp.tanh(x @ w) * 0.5 + anp.exp(-(x @ w) ** 2)
        return anp.mean(h**2) + anp.sum(anp.sqrt(w * w + 1.0))

    val, g = value_and_grad(loss)(w)
    assert val.dtype == np.float32 and g.dtype == np.float32
    ref = jax.grad(lambda w: jnp.mean((jnp.tanh(x @ w) * 0.5 + jnp.exp(-(x @ w) ** 2)) ** 2)
                   + jnp.sum(jnp.sqrt(w * w + 1.0)))(w.astype(np.float64))
    np.testing.assert_allclose(g, ref, rtol=1e-4)


def test_missing_vjp_raises_naming_the_primitive():
    @primitive
    def mystery(x):
        return x * 2

    assert mystery(np.ones(2)).tolist() == [2.0, 2.0]  # untraced: just runs
    with pytest.raises(NotImplementedError, match="mystery"):
        grad(lambda x: anp.sum(mystery(x)))(np.ones(2))

    @primitive
    def half(x, y):
        return x * y

    defvjp(half, lambda g, ans, x, y: g * y)  # no VJP for y
    np.testing.assert_array_equal(grad(lambda x: half(x, 3.0))(2.0), 3.0)
    with pytest.raises(NotImplementedError, match="half.*argument 1"):
        grad(lambda y: half(2.0, y))(1.0)


def test_wrong_vjp_shape_is_reported():
    @primitive
    def bad(x):
        return x.sum()

    defvjp(bad, lambda g, ans, x: g)  # forgot to broadcast back
    with pytest.raises(ValueError, match="VJP of 'bad'.*shape"):
        grad(bad)(np.ones(3))


def test_defvjp_fwd_keeps_residuals_only_when_traced():
    calls = {"fwd": 0}

    @primitive
    def softplus(x):
        return np.log1p(np.exp(x))

    def fwd(x):
        calls["fwd"] += 1
        e = np.exp(x)
        return np.log1p(e), e / (1 + e)

    defvjp_fwd(softplus, fwd, lambda g, sig: (g * sig,))
    x = np.array([-1.0, 0.5, 2.0])
    softplus(x)
    assert calls["fwd"] == 0
    g = grad(lambda x: anp.sum(softplus(x) * x))(x)
    assert calls["fwd"] == 1
    np.testing.assert_allclose(g, jax.grad(lambda x: jnp.sum(jax.nn.softplus(x) * x))(x))


def test_higher_order_is_refused_clearly():
    with pytest.raises(NotImplementedError, match="higher-order"):
        grad(lambda x: grad(lambda y: y * y)(x))(1.0)


def test_unbroadcast():
    g = np.ones((2, 3, 4))
    assert unbroadcast((3, 1), g).shape == (3, 1) and unbroadcast((3, 1), g)[0, 0] == 8
    assert unbroadcast(np.ones(4, np.float32), g).dtype == np.float32
    assert unbroadcast((), g) == 24.0
    np.testing.assert_array_equal(unbroadcast((2, 3, 4), g), g)


def test_check_grads_reports_and_catches_a_wrong_vjp():
    rng = np.random.default_rng(0)
    report = check_grads(lambda x, p: anp.sum(anp.sin(x) * p["w"]), rng.normal(size=(2, 3)),
                         {"w": rng.normal(size=3)}, verbose=False)
    assert report.passed and report.n_checked == 9 and report.max_abs_err < 1e-8

    @primitive
    def wrong_sin(x):
        return np.sin(x)

    defvjp(wrong_sin, lambda g, ans, x: g * np.cos(x) * 1.01)  # a 1 % error
    with pytest.raises(AssertionError, match=r"FAILED.*argument 1\['w'\] index \("):
        check_grads(lambda x, p: anp.sum(x) + anp.sum(wrong_sin(p["w"])),
                    rng.normal(size=2), {"w": rng.normal(size=3)}, verbose=False)
    with pytest.raises(ValueError, match="eps"):
        check_grads(lambda x: x, 1.0, eps=0.0)


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


# ---------------------------------------------------------------------------
# The fast paths of the common cases give the general paths' answers
# ---------------------------------------------------------------------------
def test_value_and_grad_pauses_the_garbage_collector_and_restores_it():
    import gc

    seen = []

    def f(x):
        seen.append(gc.isenabled())
        return anp.sum(x * x)

    def fails(x):
        raise ValueError("inside the traced function")

    was = gc.isenabled()
    try:
        gc.enable()
        np.testing.assert_allclose(grad(f)(np.ones(3)), 2.0 * np.ones(3))
        assert seen == [False] and gc.isenabled()  # paused while tracing, restored after
        with pytest.raises(ValueError, match="inside the traced function"):
            grad(fails)(np.ones(3))
        assert gc.isenabled()  # restored after an error too
        gc.disable()
        grad(f)(np.ones(3))
        assert not gc.isenabled()  # a caller's disabled collector stays disabled
        gc.enable()
        inner = []

        def outer(x):  # a gradient taken (of plain values) inside another one's trace
            grad(f)(np.ones(2))
            inner.append(gc.isenabled())  # the inner call left the outer pause alone
            return anp.sum(x)

        grad(outer)(np.ones(2))
        assert seen[-1] is False and inner == [False] and gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


@SETTINGS
@given(shapes2=pairs, seed=seeds, which=st.sampled_from(["maximum", "minimum", "clip"]))
def test_maximum_minimum_ties_share_like_jax(shapes2, seed, which):
    # values on a grid of three, so ties between x and y are frequent (and sometimes absent)
    (sx, sy), _ = shapes2
    rng = np.random.default_rng(seed)
    x = rng.integers(-1, 2, size=sx).astype(np.float64)
    y = rng.integers(-1, 2, size=sy).astype(np.float64)
    w = rng.normal(size=np.broadcast_shapes(sx, sy))
    ops = {"maximum": lambda xp, a, b: xp.maximum(a, b),
           "minimum": lambda xp, a, b: xp.minimum(a, b),
           "clip": lambda xp, a, b: xp.clip(a + 0 * b, 0.0, 1.0) * b}
    op = ops[which]
    ours = grad(lambda a, b: anp.sum(op(anp, a, b) * w), argnums=(0, 1))(x, y)
    ref = jax.grad(lambda a, b: jnp.sum(op(jnp, a, b) * w), argnums=(0, 1))(x, y)
    for g, r in zip(ours, ref):
        # weights 1, 1/2, 0; only the order of the broadcasting sums may differ
        np.testing.assert_allclose(g, np.asarray(r), rtol=1e-12, atol=1e-12)


@SETTINGS
@given(shape=hnp.array_shapes(min_dims=1, max_dims=3, min_side=1, max_side=3), seed=seeds,
       data=st.data())
def test_concatenate_gradient_splits_along_any_axis(shape, seed, data):
    axis = data.draw(st.integers(-len(shape), len(shape) - 1))
    sizes = data.draw(st.lists(st.integers(1, 3), min_size=1, max_size=3))
    rng = np.random.default_rng(seed)
    parts = []
    for n in sizes:
        s = list(shape)
        s[axis] = n
        parts.append(rng.normal(size=s))
    total = np.concatenate(parts, axis=axis)
    w = rng.normal(size=total.shape)
    nums = tuple(range(len(parts)))
    ours = grad(lambda *p: anp.sum(anp.concatenate(p, axis=axis) * w), argnums=nums)(*parts)
    pieces = np.split(w, np.cumsum(sizes)[:-1], axis=axis)
    for g, ref in zip(ours, pieces):
        np.testing.assert_array_equal(g, ref)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_reduction_and_index_gradients_are_fresh_writable_arrays_of_the_input_dtype(dtype):
    x = np.arange(24, dtype=dtype).reshape(2, 3, 4)
    max_hit = np.zeros((2, 3, 4), dtype)
    max_hit[:, 2, 3] = 1.0  # the largest entry of each x[i]
    index_hit = np.zeros((2, 3, 4), dtype)
    index_hit[1, 2] += 1.0
    index_hit[..., 0] += 1.0
    cases = [
        (lambda v: anp.sum(anp.sum(v, axis=(0, -1)) * 2.0), np.full(x.shape, 2.0, dtype)),
        (lambda v: anp.sum(anp.mean(v, axis=-2, keepdims=True)),
         np.full(x.shape, dtype(1.0) / dtype(3.0), dtype)),
        (lambda v: anp.sum(anp.max(v, axis=(1, 2))), max_hit),
        (lambda v: v[1, np.int64(2)].sum() + v[..., 0].sum(), index_hit),
    ]
    for f, want in cases:
        g = grad(f)(x)
        assert g.dtype == dtype and g.shape == x.shape and g.flags.writeable
        np.testing.assert_array_equal(g, want)
