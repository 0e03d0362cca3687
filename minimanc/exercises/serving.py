"""Chapter 0 — the notebook's side of grading: answering the tests' calls.

In the notebook being graded, :func:`minimanc.exercises.grade` replaces each grade cell by
a call of :func:`serve`. It connects to the tests' process
(:mod:`~minimanc.exercises.checker`), says which functions the exercises' names are, and
answers calls until the grade cell is over: each call runs the student's function on
copies of the tests' arguments and sends back its value (or its exception) as plain data
(:mod:`~minimanc.exercises.wire`). While it serves, the library functions the exercise
``forbids`` raise (:func:`~minimanc.exercises.shadowing.shadow`).

Nothing here needs protecting: this module runs among the student's cells, and whatever
they do to it changes only the answers the student sends, never the tests.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from multiprocessing.connection import Client
from typing import Any

from minimanc import autodiff
from minimanc.autodiff import numpy as anp
from minimanc.exercises.shadowing import shadow
from minimanc.exercises.values import RefusedAnswer
from minimanc.exercises.wire import Wire

__all__ = ["serve"]


def serve(address: Sequence, authkey: str, gid: str, token: str, exercise: str,
          forbids: Sequence[str], names: Sequence[str], namespace: dict) -> None:
    """Answer the tests of grade cell ``gid`` with the functions in ``namespace``.

    ``names`` are the names the solution cells define; each one the notebook binds goes to
    the tests (a function as a handle, data as data). Returns when the tests say they are
    done; a connection that breaks ends it too (the tests score what they saw).
    """
    guard = shadow(list(forbids), exercise, namespace) if forbids else None
    conn = None
    try:
        conn = Client(tuple(address), authkey=bytes.fromhex(authkey))
        wire = Wire(conn, "notebook", namespace)
        answers, refused = {}, {}
        for name in names:
            if name not in namespace:
                continue
            value = namespace[name]
            if callable(value):
                wire.offer(value, name)
            else:
                try:
                    wire.encode(value)
                except RefusedAnswer as exc:
                    refused[name] = str(exc)
                    continue
            answers[name] = value
        wire.send(("hello", gid, token, answers, refused))
        residuals: dict[int, tuple] = {}
        while True:
            try:
                message = wire.recv()
            except (EOFError, OSError):
                return   # the tests are gone: they score what they saw
            except Exception as exc:  # noqa: BLE001 - e.g. a class of the tests' cell
                wire.send(("raise", exc, []))
                continue
            if message[0] == "done":
                return
            _reply(wire, message, residuals)
    finally:
        if conn is not None:
            conn.close()
        if guard is not None:
            guard.restore()


def _reply(wire: Wire, message: tuple, residuals: dict[int, tuple]) -> None:
    """Run one request of the tests and send the reply (a value, or the exception)."""
    kind, hid = message[0], message[1]
    name = wire.names.get(hid, "a function")
    try:
        if kind == "call":
            value = wire.callables[hid](*message[2], **message[3])
        elif kind == "forward":
            fn, args, kwargs, diff = wire.callables[hid], *message[2:5]
            value = fn(*args, **kwargs)
            residuals[len(residuals) + 1] = (fn, args, kwargs, diff,
                                             isinstance(value, (tuple, list)))
            value = (value, len(residuals))
        elif kind == "backward":
            value = _backward(*residuals[message[2]], message[3])
        else:
            raise RuntimeError(f"unknown request {kind!r}")
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:  # noqa: BLE001 - the student's exception goes to the tests
        _send_reply(wire, ("raise", exc, wire.collect()), name)
        return
    _send_reply(wire, ("return", value, wire.collect()), name)


def _send_reply(wire: Wire, reply: tuple, name: str) -> None:
    """Send ``reply``; a value the tests would refuse becomes the refusal, named."""
    try:
        wire.send(reply)
        return
    except RefusedAnswer as exc:
        try:   # the value itself, or an argument the call changed?
            wire.encode(reply[:2] + ([],))
            refused = RefusedAnswer(f"{name} left an argument holding {exc}")
        except RefusedAnswer:
            refused = RefusedAnswer(f"{name} returned {exc}")
    except Exception as exc:  # noqa: BLE001 - e.g. an exception whose str() fails
        refused = RuntimeError(f"{name}: its result cannot be sent ({type(exc).__name__})")
    with contextlib.suppress(RefusedAnswer):
        wire.send(("raise", refused, reply[2]))
        return
    wire.send(("raise", refused, []))


def _backward(fn: Callable, args: tuple, kwargs: dict, diff: Sequence[int], multi: bool,
              g: Any) -> tuple:
    """The cotangents of the arguments at ``diff`` for the output cotangent ``g``: the
    gradient of ``sum(out * g)`` by ``minimanc.autodiff`` (the student's ``xp`` code)."""

    def loss(*traced):
        full = list(args)
        for i, value in zip(diff, traced):
            full[i] = value
        out = fn(*full, **kwargs)
        total = 0.0
        for o, gk in zip(out if multi else (out,), g if multi else (g,)):
            total = total + anp.sum(o * gk)
        return total

    grads = autodiff.grad(loss, argnums=tuple(range(len(diff))))(*[args[i] for i in diff])
    return tuple(grads)
