"""Chapter 0 — the tests' process: grade cells run where a student's cell cannot reach them.

:func:`minimanc.exercises.grade` starts this process (:class:`TestsProcess`) next to the
notebook's kernel, before any student cell runs. It executes the solutions notebook's own
plain cells (never its solution cells, never a student cell) and, when the kernel reaches
a grade cell, that grade cell: the names the exercises define are the notebook's, as
stand-ins (:class:`NotebookFunction`) whose calls go to the kernel
(:mod:`~minimanc.exercises.serving`) and whose results come back as plain data
(:mod:`~minimanc.exercises.wire`). NumPy, ``math``, the builtins, the library and the
comparisons are this process's own, so nothing a student cell patches, rewrites or
subclasses is used by the tests. A grade cell may differentiate a notebook function with
``engine("numpy")`` (its gradient is computed in the kernel, one backward call per
cotangent); a JAX transformation of one cannot cross processes and raises a ``TypeError``.

The verdicts go to the grader on this process's standard output (the cells' prints go to
``os.devnull``), each line signed with a key the notebook never sees: another process of
the same user may write into the pipe, not sign. What stays out of reach of this design is
the operating system: code that runs as the grading user can still edit installed files
or debug this process (a notebook one does not trust is graded in a container).
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import hashlib
import hmac
import json
import os
import queue
import secrets
import subprocess
import sys
import tempfile
import threading
import types
from collections.abc import Sequence
from multiprocessing.connection import Client, Listener
from pathlib import Path
from typing import Any

from minimanc.autodiff import Box, custom_vjp
from minimanc.exercises.markers import BEGIN_HIDDEN, END_HIDDEN
from minimanc.exercises.values import RefusedAnswer
from minimanc.exercises.wire import Wire

__all__ = [
    "NotebookFunction",
    "TestsProcess",
    "TestsStopped",
    "instrument_grade_source",
    "read_names",
    "run_tests",
]

_PART = "_minimanc_grading_part"
_REPLY_GRACE = 30   # seconds beyond the cell timeout that a reply may take
_HELLO_WAIT = 30    # seconds a connection has to say which grade cell it serves


def read_names(source: str) -> set[str]:
    """Names a cell reads and never binds (empty when it is not valid Python)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return set()
    names = [n for n in ast.walk(tree) if isinstance(n, ast.Name)]
    bound = {n.id for n in names if not isinstance(n.ctx, ast.Load)}
    bound |= {n.name for n in ast.walk(tree)
              if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}
    return {n.id for n in names if isinstance(n.ctx, ast.Load)} - bound


def instrument_grade_source(source: str) -> tuple[str, bool]:
    """The grade cell to execute, recording whether a hidden test is running.

    Returns the source and whether hidden regions could be labelled (the marker lines
    become assignments at their indentation; if that is not valid Python the cell runs
    unlabelled).
    """
    labelled = []
    for line in source.split("\n"):
        stripped = line.strip()
        indent = line[: len(line) - len(line.lstrip())]
        if stripped.startswith(BEGIN_HIDDEN):
            labelled.append(f'{indent}{_PART} = "hidden"')
        elif stripped.startswith(END_HIDDEN):
            labelled.append(f'{indent}{_PART} = "visible"')
        else:
            labelled.append(line)
    candidate = f'{_PART} = "visible"\n' + "\n".join(labelled)
    try:
        ast.parse(candidate)
        return candidate, True
    except SyntaxError:
        return f'{_PART} = "visible"\n' + source, False


def _one_line(text: Any, limit: int = 200) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _signed(text: str, key: str) -> str:
    """``text`` preceded by its HMAC-SHA256 under ``key``."""
    return hmac.new(bytes.fromhex(key), text.encode(), hashlib.sha256).hexdigest() + " " + text


def _holds(values: Sequence, kind: type | None) -> bool:
    """Whether an instance of ``kind`` is among ``values`` or inside their tuples, lists
    and dicts (a pytree's leaves, whatever its keys)."""
    if kind is None:
        return False
    stack, seen = list(values), set()
    while stack:
        value = stack.pop()
        if isinstance(value, kind):
            return True
        if isinstance(value, (tuple, list, dict)) and id(value) not in seen:
            seen.add(id(value))
            stack += value.values() if isinstance(value, dict) else value
    return False


def _tracer_class() -> type | None:
    return getattr(getattr(sys.modules.get("jax"), "core", None), "Tracer", None)


# ------------------------------------------------------------------------ the stand-ins
class NotebookFunction:
    """A function of the notebook as the tests call it: the arguments go to the kernel as
    copies, the result comes back as plain data, an exception as its class and message."""

    def __init__(self, wire: Wire, hid: int) -> None:
        self.wire, self.hid = wire, hid
        self.name = "a function of the notebook"

    def __repr__(self) -> str:
        return f"<function {self.name} of the notebook>"

    @property
    def __name__(self) -> str:
        return self.name

    def __call__(self, *args, **kwargs):
        if _holds([args, kwargs], _tracer_class()):
            raise TypeError(f"{self.name} was called with a JAX tracer: the notebook's "
                            "functions run in another process, where JAX cannot trace them "
                            "(differentiate with engine('numpy'), or compare values)")
        if _holds([args, kwargs], Box):
            return self.traced(args, kwargs)
        return self.request("call", self.hid, args, kwargs)

    def traced(self, args: tuple, kwargs: dict):
        """A call on traced values (``engine("numpy")``): one tape node whose backward pass
        asks the kernel for the vector-Jacobian product of the student's function."""
        if _holds([kwargs], Box):
            raise TypeError(f"{self.name}: a traced keyword argument; pass traced values "
                            "positionally")
        diff = tuple(i for i, a in enumerate(args) if _holds([a], Box))
        static = tuple(i for i in range(len(args)) if i not in diff)
        node = custom_vjp(lambda *a: self.request("call", self.hid, a, kwargs), static)
        node.defvjp(lambda *a: self.request("forward", self.hid, a, kwargs, diff),
                    lambda *rest: tuple(self.request("backward", self.hid, rest[-2],
                                                     rest[-1])))
        return node(*args)

    def request(self, *message):
        wire = self.wire
        if wire.conn is None:
            raise RuntimeError(f"{self.name}: its grade cell has ended; the notebook's "
                               "functions answer only while a grade cell runs")
        wire.send(message)
        if not wire.conn.poll(wire.patience):
            raise TimeoutError(f"{self.name}: no answer from the notebook within "
                               f"{wire.patience:.0f} s")
        try:
            reply = wire.recv()
        except (EOFError, OSError):
            raise ConnectionError(f"{self.name}: the notebook stopped answering (its cell "
                                  "was interrupted or its kernel died)") from None
        except RefusedAnswer as exc:
            raise RefusedAnswer(f"{self.name} returned {exc}") from None
        if not (isinstance(reply, tuple) and len(reply) == 3 and reply[0] in ("return",
                                                                              "raise")):
            raise RefusedAnswer(f"{self.name}: a reply the tests cannot read")
        if reply[0] == "raise":
            if not isinstance(reply[1], BaseException):
                raise RefusedAnswer(f"{self.name}: a reply the tests cannot read")
            raise reply[1]
        if isinstance(reply[1], NotebookFunction):
            reply[1].name = f"the function returned by {self.name}"
        return reply[1]


# ------------------------------------------------------------------- the process's main
class _Tests:
    """The solutions notebook's plain cells and grade cells, run in this process."""

    def __init__(self, plan: dict, channel) -> None:
        self.plan, self.channel = plan, channel
        module = types.ModuleType("__main__")
        sys.modules["__main__"] = module
        self.namespace = module.__dict__
        self.namespace["__builtins__"] = builtins
        self.classes: dict[str, type] = {}
        self.position = 0
        self.cells = plan["cells"]
        self.grade_at = {c["gid"]: k for k, c in enumerate(self.cells) if c["kind"] == "grade"}

    def say(self, **message) -> None:
        """One line to the grader, signed with the key only the grader and this process
        know (another process of the user could write into the pipe, not sign)."""
        self.channel.write(_signed(json.dumps(message), self.plan["channel_key"]) + "\n")
        self.channel.flush()

    def preload(self) -> None:
        """Import what the plain cells import, one statement at a time, before the
        notebook starts (a student cell then cannot change those modules' files first)."""
        for cell in self.cells:
            try:
                tree = ast.parse(cell["source"]) if cell["kind"] == "plain" else None
            except SyntaxError:
                continue
            for node in tree.body if tree else ():
                if isinstance(node, (ast.Import, ast.ImportFrom)):
                    with contextlib.suppress(Exception):   # the cell itself reports it
                        exec(compile(ast.Module([node], []), "<imports>", "exec"),  # noqa: S102
                             self.namespace)

    def run_until(self, target: int) -> None:
        while self.position < target:
            cell = self.cells[self.position]
            if cell["kind"] == "plain":
                self.run_plain(cell)
            self.position += 1
            self.say(cell=self.position)
        self.position = max(self.position, target + 1)

    def run_plain(self, cell: dict) -> None:
        try:
            exec(compile(cell["source"], f"<cell {cell['index']}>", "exec"),  # noqa: S102
                 self.namespace)
        except BaseException as exc:  # noqa: BLE001 - reported, the next cells still run
            if not cell.get("raises"):
                self.say(setup=cell["index"], error=f"{type(exc).__name__}: {_one_line(exc)}")
        for name, value in list(self.namespace.items()):
            if isinstance(value, type) and value.__module__ == "__main__":
                self.classes[name] = value
        pyplot = sys.modules.get("matplotlib.pyplot")
        if pyplot is not None:
            pyplot.close("all")

    def serve(self, listener: Listener, gid: str) -> None:
        token = self.plan["tokens"][gid]
        while True:
            try:
                conn = listener.accept()
            except (OSError, EOFError, ValueError):   # a connection without the key
                continue
            if conn.poll(_HELLO_WAIT):
                wire = Wire(conn, "tests", self.namespace, self.classes, NotebookFunction,
                            self.plan["timeout"] + _REPLY_GRACE)
                with contextlib.suppress(RefusedAnswer, EOFError, OSError):
                    hello = wire.recv()
                    if hello == ("skip", gid, token):   # the grader: this cell will not come
                        conn.close()
                        self.say(verdict=gid, skipped=True)
                        return
                    if isinstance(hello, tuple) and len(hello) == 5 and \
                            hello[:3] == ("hello", gid, token) and \
                            isinstance(hello[3], dict) and isinstance(hello[4], dict):
                        break
            conn.close()
        try:
            self.say(verdict=gid, **self.grade(wire, self.cells[self.grade_at[gid]],
                                               hello[3], hello[4]))
            with contextlib.suppress(OSError, ValueError):
                wire.send(("done",))
        finally:
            wire.conn = None
            conn.close()

    def grade(self, wire: Wire, cell: dict, answers: dict, refused: dict) -> dict:
        source = cell["source"]
        for name in self.plan["answers"]:
            value = answers.get(name, self)
            if value is self:
                self.namespace.pop(name, None)
            else:
                self.namespace[name] = value
                if isinstance(value, NotebookFunction):
                    value.name = name
        code, labelled = instrument_grade_source(source)
        self.namespace[_PART] = "visible"
        try:
            for name in sorted(read_names(source)):
                if name in refused and isinstance(refused[name], str):
                    raise RefusedAnswer(f"{name} is {refused[name]}")
            exec(compile(code, f"<grade cell {cell['gid']}>", "exec"),  # noqa: S102
                 self.namespace)
        except BaseException as exc:  # noqa: BLE001 - whatever fails, the grade cell fails
            hidden = labelled and self.namespace.get(_PART) == "hidden"
            message = _one_line(exc)
            return {"passed": False, "hidden": hidden,
                    "message": f"{type(exc).__name__}: {message}" if message
                    else type(exc).__name__}
        return {"passed": True, "hidden": False, "message": ""}


def run_tests() -> None:
    """The tests' process: read the plan on stdin, answer on the original stdout."""
    channel = os.fdopen(os.dup(1), "w", encoding="utf-8")
    quiet = os.open(os.devnull, os.O_WRONLY)
    os.dup2(quiet, 1)
    sys.stdout = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115 - for the process
    plan = json.loads(sys.stdin.readline())

    def watch_stdin() -> None:   # the grader gone (stdin closed): stop
        sys.stdin.read()
        os._exit(0)

    threading.Thread(target=watch_stdin, daemon=True).start()
    tests = _Tests(plan, channel)
    tests.preload()
    listener = Listener(("127.0.0.1", 0), authkey=bytes.fromhex(plan["authkey"]))
    tests.say(address=list(listener.address))
    for gid in plan["order"]:
        tests.run_until(tests.grade_at[gid])
        tests.say(ready=gid)
        tests.serve(listener, gid)
    tests.say(finished=True)


# ------------------------------------------------------------------- the grader's side
class TestsStopped(RuntimeError):
    """The tests' process ended or stalled before it answered."""


class TestsProcess:
    """The grader's handle on the tests' process: start it with the solutions notebook's
    cells, wait until it is ready for a grade cell, read its verdicts, stop it.

    ``cells`` are the solutions notebook's code cells other than solution cells, each a
    dict ``kind`` ("plain" or "grade"), ``source``, ``index``, ``gid`` (grade cells) and
    ``raises`` (a plain cell tagged ``raises-exception``); ``order`` the grade ids in the
    order the kernel will reach them; ``answers`` the names the solution cells define.
    """

    def __init__(self, cells: list[dict], order: list[str], answers: list[str],
                 folder: Path, timeout: int, python: str | None = None) -> None:
        self.timeout = timeout
        self.authkey = secrets.token_hex(16)
        self.channel_key = secrets.token_hex(32)   # never sent to the notebook
        self.tokens = {gid: secrets.token_hex(8) for gid in order}
        self.lines: queue.Queue = queue.Queue()
        self.verdicts: dict[str, dict] = {}
        self.ready: set[str] = set()
        self.setup_errors: list[str] = []
        self.ended = False
        self.log = tempfile.TemporaryFile("w+", encoding="utf-8")  # noqa: SIM115 - stop()
        env = {**os.environ, "MPLBACKEND": "Agg"}
        self.process = subprocess.Popen(
            [python or sys.executable, "-c",
             "from minimanc.exercises.checker import run_tests; run_tests()"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, cwd=folder,
            env=env, text=True, encoding="utf-8")
        plan = {"cells": cells, "order": order, "answers": answers, "authkey": self.authkey,
                "tokens": self.tokens, "timeout": timeout, "channel_key": self.channel_key}
        self.process.stdin.write(json.dumps(plan) + "\n")
        self.process.stdin.flush()
        threading.Thread(target=self._read, daemon=True).start()
        self.address: list | None = None

    def started(self) -> None:
        """Block until the process has imported what the plain cells import and listens
        (the notebook's kernel starts meanwhile; its first cell must wait for this)."""
        if self.address is None:
            self.address = self._wait(lambda m: m.get("address"), max(self.timeout, 120),
                                      "did not start")

    def _read(self) -> None:
        for line in self.process.stdout:
            mac, _, text = line.rstrip("\n").partition(" ")
            if hmac.compare_digest(mac, _signed(text, self.channel_key).partition(" ")[0]):
                with contextlib.suppress(json.JSONDecodeError):
                    self.lines.put(json.loads(text))
        self.lines.put(None)

    def _wait(self, want, patience: float, what: str):
        """Read messages until ``want(message)`` is truthy; ``patience`` seconds without
        any message from the process (a plain cell that hangs) is a stall."""
        while True:
            if self.ended and self.lines.empty():
                raise TestsStopped(f"the tests' process {what}: it ended{self._last_words()}")
            try:
                message = self.lines.get(timeout=patience)
            except queue.Empty:
                raise TestsStopped(f"the tests' process {what}: no progress in "
                                   f"{patience:.0f} s") from None
            if message is None:
                self.ended = True
                continue
            if "verdict" in message:
                self.verdicts.setdefault(message["verdict"], message)
            elif "ready" in message:
                self.ready.add(message["ready"])
            elif "setup" in message:
                self.setup_errors.append(f"cell {message['setup']}: {message['error']}")
            found = want(message)
            if found:
                return found

    def _last_words(self) -> str:
        """The last line the process wrote on stderr (why it ended), if any."""
        with contextlib.suppress(OSError, ValueError):
            self.log.seek(0)
            lines = [line.strip() for line in self.log.read().splitlines() if line.strip()]
            if lines:
                return f" ({_one_line(lines[-1], 160)})"
        return ""

    def wait_ready(self, gid: str) -> None:
        """Block until the process has run the plain cells before ``gid`` and listens."""
        if gid not in self.ready:
            self._wait(lambda m: m.get("ready") == gid, self.timeout, "stalled")

    def verdict(self, gid: str, patience: float = 2.0) -> dict | None:
        """The verdict on ``gid`` (None when it did not come within ``patience`` s)."""
        if gid not in self.verdicts:
            with contextlib.suppress(TestsStopped):
                self._wait(lambda m: m.get("verdict") == gid, patience, "stopped")
        return self.verdicts.get(gid)

    def skip(self, gid: str) -> None:
        """Tell the process that grade cell ``gid`` will not be served (its serving cell
        ended without a verdict), so it moves on to the next one."""
        with contextlib.suppress(OSError, EOFError, ValueError, TestsStopped):
            self.started()
            conn = Client(tuple(self.address), authkey=bytes.fromhex(self.authkey))
            try:
                Wire(conn, "notebook", {}).send(("skip", gid, self.tokens[gid]))
            finally:
                conn.close()

    def serve_source(self, gid: str, exercise: str, forbids: list[str],
                     names: list[str]) -> str:
        """The cell the kernel runs in place of grade cell ``gid``."""
        self.started()
        args = (list(self.address), self.authkey, gid, self.tokens[gid], exercise, forbids,
                names)
        return ("import minimanc.exercises.serving as _minimanc_serving\n"
                f"_minimanc_serving.serve(*{args!r}, globals())\ndel _minimanc_serving")

    def stop(self) -> None:
        with contextlib.suppress(OSError):
            self.process.stdin.close()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.log.close()
        while not self.lines.empty():
            message = self.lines.get_nowait()
            if message and "setup" in message:
                self.setup_errors.append(f"cell {message['setup']}: {message['error']}")
