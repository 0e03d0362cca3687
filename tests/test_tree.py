"""minimanc.tree: map, cast_floats, leaves, flatten / unflatten."""

import importlib
from typing import NamedTuple

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import train, tree


class Pair(NamedTuple):
    a: object
    b: object


_dtypes = st.sampled_from([np.float16, np.float32, np.float64, np.int8, np.int32, np.int64,
                           np.uint8, np.bool_])
_leaf = st.builds(lambda dt, n, seed: np.random.default_rng(seed).normal(size=n).astype(dt),
                  _dtypes, st.integers(0, 3), st.integers(0, 2**16))
_keys = st.text("abcxyz", min_size=1, max_size=3)
trees = st.recursive(
    _leaf | st.none(),
    lambda kids: (st.lists(kids, max_size=3)
                  | st.lists(kids, max_size=3).map(tuple)
                  | st.builds(Pair, kids, kids)
                  | st.dictionaries(_keys, kids, max_size=3)),
    max_leaves=10,
)


def _same_structure(a, b, key_order: bool = True) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, dict):
        same_keys = list(a) == list(b) if key_order else set(a) == set(b)
        return (type(b) is dict and same_keys
                and all(_same_structure(a[k], b[k], key_order) for k in a))
    if isinstance(a, list | tuple):
        return (type(a) is type(b) and len(a) == len(b)
                and all(_same_structure(x, y, key_order) for x, y in zip(a, b)))
    return not isinstance(b, dict | list | tuple)


@given(trees)
def test_map_keeps_structure_and_visits_every_leaf_once(t):
    seen = []
    out = tree.map(lambda x: (seen.append(x), x + 0)[1], t)
    assert _same_structure(t, out)
    assert len(seen) == len(tree.leaves(t))
    for x, y in zip(tree.leaves(t), tree.leaves(out), strict=True):
        np.testing.assert_array_equal(x, y)


@given(trees, st.sampled_from([np.float32, np.float64, np.float16]))
def test_cast_floats_casts_floats_and_keeps_integers(t, dtype):
    out = tree.cast_floats(t, dtype)
    assert _same_structure(t, out)
    for x, y in zip(tree.leaves(t), tree.leaves(out), strict=True):
        assert isinstance(y, np.ndarray)
        if np.issubdtype(x.dtype, np.floating):
            assert y.dtype == dtype
            np.testing.assert_array_equal(y, x.astype(dtype))
        else:
            assert y.dtype == x.dtype
            np.testing.assert_array_equal(y, x)


@given(trees)
def test_map_of_two_trees_pairs_matching_leaves(t):
    doubled = tree.map(lambda x: x * 2, t)
    pairs = []
    out = tree.map(lambda x, y: (pairs.append((x, y)), y)[1], t, doubled)
    assert _same_structure(t, out)
    assert sorted(id(x) for x, _ in pairs) == sorted(id(z) for z in tree.leaves(t))
    for x, y in pairs:
        np.testing.assert_array_equal(y, x * 2)


def test_map_second_tree_may_hold_lists_for_tuples_and_subtrees_at_leaves():
    out = tree.map(lambda x, y: (x, y), (1, {"a": 2}), [10, {"a": [3, 4]}])
    assert out == ((1, 10), {"a": (2, [3, 4])})


@pytest.mark.parametrize("other, where", [
    ({"a": 1}, "the root"),
    ({"a": 1, "b": [1]}, r"\['b'\]"),
    ({"a": 1, "b": 2}, r"\['b'\]"),
    ({"a": 1, "b": [1, 2, 3]}, r"\['b'\]"),
])
def test_map_names_where_two_trees_differ(other, where):
    with pytest.raises(ValueError, match=f"differ in structure at {where}"):
        tree.map(lambda x, y: x, {"a": 1, "b": [1, 2]}, other)


def test_leaves_order_and_none():
    assert tree.leaves({"b": 2, "a": [1, None, (3,)]}) == [1, 3, 2]
    assert tree.leaves(None) == []


dense_trees = st.dictionaries(  # a dict root, no None, no empty container: a checkpoint's trees
    _keys,
    st.recursive(_leaf, lambda kids: (st.lists(kids, min_size=1, max_size=3)
                                      | st.dictionaries(_keys, kids, min_size=1, max_size=3)),
                 max_leaves=8),
    min_size=1, max_size=3,
)


@given(dense_trees)
def test_flatten_unflatten_round_trip(t):
    back = tree.from_flat_dict(tree.to_flat_dict(t))
    assert _same_structure(t, back, key_order=False)  # dicts come back in sorted key order
    for x, y in zip(tree.leaves(t), tree.leaves(back), strict=True):
        np.testing.assert_array_equal(x, y)


def test_flatten_keys():
    flat = tree.to_flat_dict({"b": [np.zeros(1), None, (2,)], "a": 1.0})
    assert list(flat) == ["a", "b/#0", "b/#2/#0"]


def test_train_cast_floats_is_the_tree_function():
    fit_module = importlib.import_module("minimanc.train.fit")
    assert train.cast_floats is tree.cast_floats
    assert fit_module.cast_floats is tree.cast_floats


def test_tree_flatten_paths_and_rebuild():
    t = {"b": [1.0, (2.0, 3.0)], "a": None, "c": {"x": 4.0}}
    leaves, paths, rebuild = tree.tree_flatten(t)
    assert leaves == [1.0, 2.0, 3.0, 4.0]
    assert paths == ["['b'][0]", "['b'][1][0]", "['b'][1][1]", "['c']['x']"]
    assert tree.tree_unflatten(rebuild, [2 * x for x in leaves]) == {
        "a": None, "b": [2.0, (4.0, 6.0)], "c": {"x": 8.0}}
