"""The computation graph with a cotangent on each edge (chapter 1)."""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import Graph, computation_graph, grad, nn
from minimanc.viz.graph import plot_graph

matplotlib.use("Agg")

floats = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)


def central(f, args, eps=1e-6):
    """Central differences of the scalar f with respect to every element of every argument."""
    out = []
    for k, a in enumerate(args):
        g = np.zeros_like(a)
        for idx in np.ndindex(a.shape):
            hi = [b.copy() for b in args]
            lo = [b.copy() for b in args]
            hi[k][idx] += eps
            lo[k][idx] -= eps
            g[idx] = (float(f(*hi)) - float(f(*lo))) / (2 * eps)
        out.append(g)
    return out


def test_edge_list_of_a_fixed_function_is_exactly_as_expected():
    x = 0.7
    g = computation_graph(lambda x: anp.sin(x * x) + x, np.array(x))
    assert [(n.index, n.name, n.shape) for n in g.nodes] == [
        (0, "arg0", ()), (1, "multiply", ()), (2, "sin", ()), (3, "add", ())]
    assert g.inputs == (0,) and g.output == 3
    c = math.cos(x * x)
    expected = [(2, 3, 0, 1.0), (0, 3, 1, 1.0), (1, 2, 0, c), (0, 1, 0, c * x), (0, 1, 1, c * x)]
    got = [(e.parent, e.child, e.argnum, float(e.cotangent)) for e in g.edges]
    assert [t[:3] for t in got] == [t[:3] for t in expected]
    assert np.allclose([t[3] for t in got], [t[3] for t in expected], rtol=1e-15, atol=0)
    # x is used three times: its cotangent is the sum of its three edges
    assert np.isclose(float(g.gradients()[0]), 2 * x * c + 1, rtol=1e-15)
    assert str(g).splitlines() == [
        "     sin#2 -> add#3      (arg 0)  cotangent 1.0000",
        "    arg0#0 -> add#3      (arg 1)  cotangent 1.0000",
        "multiply#1 -> sin#2      (arg 0)  cotangent 0.8823",
        "    arg0#0 -> multiply#1 (arg 0)  cotangent 0.6176",
        "    arg0#0 -> multiply#1 (arg 1)  cotangent 0.6176",
    ]


def mlp_loss(x, w, b):
    return anp.sum(anp.tanh(x @ w + b) ** 2) + anp.mean(anp.exp(w) * w)


@settings(max_examples=25, deadline=None)
@given(st.lists(floats, min_size=6, max_size=6), st.lists(floats, min_size=6, max_size=6),
       st.lists(floats, min_size=2, max_size=2))
def test_edge_cotangents_sum_to_the_gradient_and_match_central_differences(xs, ws, bs):
    args = (np.array(xs).reshape(2, 3), np.array(ws).reshape(3, 2), np.array(bs))
    g = computation_graph(mlp_loss, *args)
    by_edges = g.gradients()
    by_grad = grad(mlp_loss, argnums=(0, 1, 2))(*args)
    for mine, ref in zip(by_edges, by_grad):
        assert mine.shape == ref.shape and np.array_equal(mine, ref)  # same sums, same order
    for mine, fd in zip(by_edges, central(mlp_loss, args)):
        assert np.allclose(mine, fd, atol=1e-6), (mine, fd)


@settings(max_examples=25, deadline=None)
@given(floats, floats)
def test_every_node_cotangent_is_the_sum_of_its_outgoing_edges(x, y):
    def f(x, y):
        a = x * y
        return anp.sin(a) + a * anp.exp(y) - y

    g = computation_graph(f, np.array(x), np.array(y))
    assert float(g.cotangent(g.output)) == 1.0
    for node in g.nodes:
        out_edges = [e for e in g.edges if e.parent == node.index]
        if node.index != g.output:
            assert out_edges, f"node {node.name}#{node.index} reaches the output"
            assert np.isclose(g.cotangent(node.index), sum(e.cotangent for e in out_edges))
        for e in out_edges:  # an edge's cotangent has its parent's shape
            assert np.shape(e.cotangent) == node.shape
    a = x * y  # the cotangent of a = x y, by hand: cos(a) + exp(y)
    mult = next(n for n in g.nodes if n.name == "multiply" and g.edges[-1].child == n.index)
    assert np.isclose(g.cotangent(mult.index), math.cos(a) + math.exp(y))


def test_custom_vjp_primitives_and_float32_are_kept():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((1, 5, 5, 2)).astype(np.float32)
    w = rng.standard_normal((3, 3, 2, 3)).astype(np.float32)

    def f(x, w):
        return anp.sum(nn.relu(nn.conv2d(x, w, None, 2, 1)))

    g = computation_graph(f, x, w)
    assert [n.name for n in g.nodes][2:] == ["_conv2d_nob", "relu", "sum"]
    gx, gw = g.gradients()
    assert gx.dtype == np.float32 and gw.dtype == np.float32
    rx, rw = grad(f, argnums=(0, 1))(x, w)
    assert np.array_equal(gx, rx) and np.array_equal(gw, rw)


def test_an_unused_argument_gets_zero_and_no_edges():
    g = computation_graph(lambda x, y: anp.sum(x * 2.0), np.ones(3), np.ones(2))
    assert all(e.parent != 1 for e in g.edges)
    assert np.array_equal(g.gradients()[1], np.zeros(2))
    assert np.array_equal(g.gradients()[0], np.full(3, 2.0))
    const = computation_graph(lambda x: np.float64(3.0), np.ones(2))
    assert const.edges == () and np.array_equal(const.gradients()[0], np.zeros(2))


def test_draw_puts_one_label_per_node_and_per_edge():
    import matplotlib.pyplot as plt

    g = computation_graph(lambda x, y: anp.sin(x * y) + x * anp.exp(y), np.array(0.4),
                          np.array(-1.2))
    fig, ax = plt.subplots()
    assert plot_graph(g, ax) is ax
    texts = [t.get_text() for t in ax.texts if t.get_text()]  # arrows are empty annotations
    assert len(texts) == len(g.nodes) + len(g.edges)
    assert "sin\n()" in texts and texts.count("1") == 2 and "0.887" in texts
    assert isinstance(g, Graph) and len(ax.texts) - len(texts) == len(g.edges)
    plt.close(fig)


@pytest.mark.parametrize("call, error, words", [
    (lambda: computation_graph(3.0, np.ones(2)), TypeError, "f must be callable"),
    (lambda: computation_graph(lambda x: x), ValueError, "args=()"),
    (lambda: computation_graph(lambda x: anp.sum(x), np.arange(3)), TypeError, "dtype int"),
    (lambda: computation_graph(lambda x: x * 2.0, np.ones(2)), TypeError, "shape (2,)"),
    (lambda: computation_graph(lambda x: (x, x), np.ones(())), TypeError, "tuple"),
    (lambda: computation_graph(lambda x: x, True), TypeError, "bool"),
    (lambda: computation_graph(lambda x: anp.sum(x), np.ones(2)).cotangent(5), ValueError,
     "index=5"),
    (lambda: computation_graph(lambda x: anp.sum(x), np.ones(2)).lines(-1), ValueError,
     "digits=-1"),
])
def test_bad_input_is_refused_with_a_clear_message(call, error, words):
    with pytest.raises(error) as info:
        call()
    assert words in str(info.value)
