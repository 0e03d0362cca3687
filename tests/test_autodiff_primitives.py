"""Tests for minimanc.autodiff (chapter 1): every primitive against central
differences and against ``jax.grad`` (float64): element-wise, reductions, linear
algebra, shapes and indexing, and plain (untraced) inputs."""

from __future__ import annotations

import hypothesis.extra.numpy as hnp
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from autodiff_strategies import SETTINGS, pairs, seeds, shapes
from hypothesis import given, settings
from hypothesis import strategies as st

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import Box, check_grads, grad
from minimanc.engine import get_engine

get_engine("jax")  # turns on jax_enable_x64


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

