"""The grader's wire, without a kernel: what crosses between the tests and a notebook.

The tests' side reads only plain data, built as its exact type (crafted messages
included); the notebook's side gets copies of the tests' arguments, and what a call
changes in them comes back; a notebook function runs as the notebook's, differentiated
with ``engine("numpy")`` through the notebook's own tape. The notebook runs here in a
thread, with :func:`minimanc.exercises.serving.serve` as in a kernel.
"""

from __future__ import annotations

import json
import struct
import threading
from multiprocessing import Pipe
from multiprocessing.connection import Listener

import numpy as np
import pytest

from minimanc import engine, exercises
from minimanc.exercises import serving
from minimanc.exercises.checker import NotebookFunction
from minimanc.exercises.wire import Wire


def send_to_tests(value, classes=None):
    """``value`` sent by a notebook's wire and read by the tests' wire."""
    here, there = Pipe()
    message = Wire(here, "notebook", {}).encode(value)
    tests = Wire(there, "tests", {}, classes or {}, NotebookFunction, 5)
    got = {}
    reader = threading.Thread(target=lambda: got.setdefault("value", tests.recv()))
    reader.start()
    here.send_bytes(message)
    reader.join()
    return got["value"]


def forged(nodes: list, root=0, buffers=()):
    """A hand-made message read by the tests' wire (what a tampered notebook could send)."""
    parts = [json.dumps({"root": root, "nodes": nodes}).encode(), *buffers]
    here, there = Pipe()
    here.send_bytes(struct.pack(f"<I{len(parts)}Q", len(parts), *map(len, parts))
                    + b"".join(parts))
    return Wire(there, "tests", {}, {}, NotebookFunction, 5).recv()


def notebook_class(name: str, bases: tuple = (), **body):
    """A class as a notebook cell defines it (module ``__main__``)."""
    return type(name, bases, {"__module__": "__main__", **body})


class Notebook:
    """A notebook serving ``namespace``'s functions in a thread, the test being the tests'
    process: ``self.fn[name]`` calls the notebook's function ``name``."""

    def __init__(self, namespace: dict, classes: dict | None = None, forbids=()) -> None:
        key = b"k" * 16
        self.listener = Listener(("127.0.0.1", 0), authkey=key)
        names = sorted(k for k in namespace if not k.startswith("__"))
        self.thread = threading.Thread(target=serving.serve, args=(
            self.listener.address, key.hex(), "g", "t", "ex", list(forbids), names, namespace))
        self.thread.start()
        self.wire = Wire(self.listener.accept(), "tests", {}, classes or {}, NotebookFunction, 30)
        hello = self.wire.recv()
        assert hello[:3] == ("hello", "g", "t")
        self.fn, self.refused = hello[3], hello[4]
        for name, value in self.fn.items():
            if isinstance(value, NotebookFunction):
                value.name = name

    def close(self) -> None:
        self.wire.send(("done",))
        self.thread.join()
        self.listener.close()


@pytest.fixture()
def notebook(request):
    made = []

    def make(namespace, **kwargs):
        made.append(Notebook(namespace, **kwargs))
        return made[-1]

    yield make
    for nb in made:
        nb.close()


# ------------------------------------------------------------------ what the tests read
@pytest.mark.parametrize("value", [
    1.0, -0.0, float("nan"), 2, 10 ** 40, True, None, "s", b"\x00b", 1 + 2j,
    (1, [2.0, {"a": 3}]), {1, 2}, frozenset({3}), slice(1, None, 2), range(3),
    np.float64(1.5), np.int32(3), np.bool_(True), np.str_("u"), np.zeros((2, 3)),
    np.array(["a", "bc"]), np.array([1.0, None], dtype=object), np.arange(6).reshape(2, 3)[:, ::2],
])
def test_plain_values_arrive_as_their_exact_type(value):
    got = send_to_tests(value)
    assert type(got) is type(value)
    if isinstance(value, np.ndarray):
        assert got.dtype == value.dtype and got.shape == value.shape
        assert [repr(x) for x in got.ravel()] == [repr(x) for x in value.ravel()]
    else:
        assert repr(got) == repr(value)


@pytest.mark.parametrize("value, message", [
    (notebook_class("S", (str,), __eq__=lambda s, o: True, __hash__=str.__hash__)("x"),
     "a S, a str subclass; return a plain str"),
    ((1.0, notebook_class("F", (float,))(2.0)), "a F, a float subclass; return a plain float"),
    (np.arange(3).view(notebook_class("A", (np.ndarray,))), "an ndarray subclass"),
    ([{"k": notebook_class("Int", (int,))(1)}], "an Int, an int subclass; return a plain int"),
    (notebook_class("D", (dict,))(), "a D, a dict subclass; return a plain dict"),
    (notebook_class("F64", (np.float64,))(1.0), "a F64, a float subclass; return a plain float"),
    (object(), "an object, not a plain type"),
])
def test_a_subclass_or_foreign_object_is_refused_in_the_notebook(value, message):
    with pytest.raises(exercises.RefusedAnswer) as info:
        send_to_tests(value)
    assert message in str(info.value)


@pytest.mark.parametrize("nodes, message", [
    ([["function", [3, 11], 0, 0, "f", "f", 0, 0, 0]], "a value of kind 'function'"),
    ([["global", "os", "system"]], "a value of kind 'global'"),
    ([["module", "os"]], "a value of kind 'module'"),
    ([["reduce", 1, 2, -1, -1, -1], ["str", "x"], ["tuple", []]], "a value of kind 'reduce'"),
    ([["obj", "__main__", "Rigged", [], None]], "an object of class Rigged, which the tests"),
    ([["obj", "os", "PathLike", [], None]], "an object of class PathLike"),
    ([["obj", "minimanc.models.config", "ModelConfig", ["__class__", 1], None]],
     "the attributes of a ModelConfig"),
    ([["ref", 7]], "a reference to an object the tests did not send"),
    ([["same", 7]], "a reference to an array never sent"),
    ([["array", "O", [1], 0]], "an array of dtype 'O'"),
    ([["array", "V8", [1], 0]], "an array of dtype 'V8'"),
    ([["array", "<f8", [2], 0]], "cannot read (ValueError"),
    ([["tuple", [0]]], "a cycle through immutable values"),
    ([["float", 1.5]], "a string was expected"),
    ([["int", True]], "a bad int"),
    ([["list", [5], None]], "a reference to node 5"),
    ([["list", [["global", "os", "system"]], None]], "a value written in place of kind"),
    (["not a node"], "node 0 is not a node"),
])
def test_the_tests_read_only_plain_data(nodes, message):
    import minimanc.models.config  # noqa: F401 - its class is the one a forged node names

    with pytest.raises(exercises.RefusedAnswer) as info:
        forged(nodes, buffers=[b"\x00" * 4])
    assert message in str(info.value)


def test_an_exception_arrives_as_its_class_and_a_notebook_class_as_the_tests_class():
    def init(self, a, b):
        self.a, self.b = a, b

    ours = notebook_class("Pair", __init__=init)
    theirs = notebook_class("Pair", __init__=init, __eq__=lambda s, o: True)
    got = send_to_tests((KeyError("k"), exercises.ForbiddenFunctionError("no"), theirs(1, [2])),
                        classes={"Pair": ours})
    assert type(got[0]) is KeyError and got[0].args == ("k",)
    assert type(got[1]) is exercises.ForbiddenFunctionError and str(got[1]) == "no"
    assert type(got[2]) is ours and (got[2].a, got[2].b) == (1, [2])


def test_a_chain_of_40000_objects_crosses_without_recursion():
    node = notebook_class("Node", __init__=lambda self, up: setattr(self, "up", up))
    chain = None
    for _ in range(40_000):
        chain = node(chain)
    got = send_to_tests(chain, classes={"Node": node})
    depth = 0
    while got is not None:
        got, depth = got.up, depth + 1
    assert depth == 40_000


# --------------------------------------------------------------- calls of the notebook
def test_arguments_cross_as_copies_and_what_a_call_changes_comes_back(notebook):
    def grow(items, table, array, rng, box):
        items.append(len(items))
        table["seen"] = True
        array *= 2
        rng.normal()
        box.n = 7
        return items, box   # the same objects as the tests' own

    holder = notebook_class("Holder")
    nb = notebook({"grow": grow, "Holder": holder}, classes={"Holder": holder})
    items, table, array = [1], {}, np.arange(3.0)
    rng, box = np.random.default_rng(0), holder()
    got = nb.fn["grow"](items, table, array, rng, box)
    assert got[0] is items and got[1] is box
    assert items == [1, 1] and table == {"seen": True} and array.tolist() == [0.0, 2.0, 4.0]
    assert box.n == 7
    drawn = np.random.default_rng(0)
    drawn.normal()
    assert rng.bit_generator.state == drawn.bit_generator.state


def test_the_tests_functions_run_in_the_notebook_by_code(notebook):
    def apply(f, x):
        return f(x)

    nb = notebook({"apply": apply})
    scale = 3.0
    assert nb.fn["apply"](lambda v: scale * v + len("ab"), 2.0) == 8.0
    assert nb.fn["apply"](np.sum, np.ones(4)) == 4.0   # a library function by name


def test_an_unchanged_array_crosses_once(notebook):
    nb = notebook({"total": lambda a: float(a.sum())})
    big = np.ones(100_000)
    sent = []
    original = nb.wire.encode

    def measured(value):
        message = original(value)
        sent.append(len(message))
        return message

    nb.wire.encode = measured
    assert nb.fn["total"](big) == 100_000.0
    assert nb.fn["total"](big) == 100_000.0
    big[0] = 2.0
    assert nb.fn["total"](big) == 100_001.0
    assert sent[0] > 800_000 and sent[1] < 1_000 and sent[2] > 800_000


def test_a_returned_function_and_an_exception_stay_the_notebooks(notebook):
    def adder(k):
        if k < 0:
            raise ValueError(f"k must be >= 0, got {k}")
        return lambda x: x + k

    nb = notebook({"adder": adder})
    plus2 = nb.fn["adder"](2)
    assert isinstance(plus2, NotebookFunction) and plus2(1) == 3
    assert plus2.name == "the function returned by adder"
    with pytest.raises(ValueError, match="k must be >= 0, got -1"):
        nb.fn["adder"](-1)


def test_a_refused_answer_names_the_function(notebook):
    rigged = notebook_class("Rigged", (float,), __eq__=lambda s, o: True, __hash__=float.__hash__)
    nb = notebook({"f": lambda: rigged(1.0), "g": lambda items: items.append(rigged(2.0))})
    with pytest.raises(exercises.RefusedAnswer, match="f returned a Rigged, a float subclass"):
        nb.fn["f"]()
    with pytest.raises(exercises.RefusedAnswer, match="g left an argument holding a Rigged"):
        nb.fn["g"]([])


def test_a_data_answer_of_a_foreign_type_is_refused_by_name(notebook):
    nb = notebook({"zeta": notebook_class("Z", (float,))(1.0), "ok": 2.0})
    assert nb.fn["ok"] == 2.0 and "zeta" not in nb.fn
    assert nb.refused["zeta"] == "a Z, a float subclass; return a plain float"


def test_a_forbidden_library_function_raises_while_served(notebook):
    from minimanc import dmp

    nb = notebook({"classify": lambda a, b: dmp.classify(a, b)},
                  forbids=["minimanc.dmp.classify"])
    with pytest.raises(exercises.ForbiddenFunctionError, match="write classify yourself"):
        nb.fn["classify"](1.0, 1.0)
    nb.close()
    assert dmp.classify(1.0, 1.0) == "underdamped"   # back once the grade cell is over
    nb.close = lambda: None


def test_engine_numpy_differentiates_a_notebook_function_through_the_notebook(notebook):
    def energy(w, x, xp=np):
        return xp.sum(w["a"] * x * x) / 2.0 + w["b"]

    nb = notebook({"energy": energy})
    eng = engine("numpy")
    x = np.array([1.0, -2.0, 3.0])
    w = {"a": np.array([1.0, 2.0, 3.0]), "b": np.array(0.5)}
    g = eng.grad(lambda w: nb.fn["energy"](w, x, xp=eng.xp))(w)
    assert np.allclose(g["a"], x * x / 2.0) and np.isclose(g["b"], 1.0)


def test_a_jax_transformation_of_a_notebook_function_is_refused_in_words(notebook):
    jax = pytest.importorskip("jax")
    nb = notebook({"square": lambda x: x * x})
    with pytest.raises(TypeError, match="called with a JAX tracer"):
        jax.grad(lambda x: nb.fn["square"](x))(1.0)
