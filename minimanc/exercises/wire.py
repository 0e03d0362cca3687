"""Chapter 0 — the grader's wire: one end of the connection between the tests and a notebook.

The tests of a notebook run in a process of their own (:mod:`~.checker`), the student's
functions in the notebook's kernel (:mod:`~.serving`); a :class:`Wire` at each end sends
values as messages: a JSON header of nodes (:mod:`~.encoding`) followed by the arrays'
bytes, read back by :mod:`~.decoding`. What may cross, and how the notebook's copies of
the tests' objects (mirrors) are kept in step, is :mod:`~.values`.
"""

from __future__ import annotations

import contextlib
import gc
import json
import struct
from collections.abc import Callable
from typing import Any

from minimanc.exercises.decoding import Decoder
from minimanc.exercises.encoding import Encoder
from minimanc.exercises.values import RefusedAnswer, changed

__all__ = ["Wire"]


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off: a message of 100,000 nodes makes as many
    objects, none of them garbage, and each collection would walk the whole heap."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()

_LIMIT = 1 << 31  # bytes in one message part
_BAD_MESSAGE = (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError,
                IndexError, AttributeError, OverflowError, struct.error)


class Wire:
    """One end of the connection between the tests' process (``side="tests"``) and the
    notebook's kernel (``side="notebook"``): :meth:`send` encodes a value, :meth:`recv`
    decodes one (strictly on the tests' side, see the module docstring).

    ``namespace`` is the notebook's globals (where ``__main__`` names resolve) or the
    tests'; ``classes`` maps the names of the notebook classes the tests accept to the
    tests' classes; ``proxy`` is the tests' class of stand-ins for a notebook function
    (built as ``proxy(wire, hid)``, read back through its ``hid``); ``patience`` how many
    seconds the tests wait for a reply.
    """

    def __init__(self, conn, side: str, namespace: dict, classes: dict | None = None,
                 proxy: type | None = None, patience: float = 0.0) -> None:
        if side not in ("tests", "notebook"):
            raise ValueError(f"side must be 'tests' or 'notebook', got {side!r}")
        self.conn, self.tests, self.namespace = conn, side == "tests", namespace
        self.classes, self.proxy, self.patience = classes or {}, proxy, patience
        self.originals: dict[int, Any] = {}      # tests: cid -> the tests' object
        self.cids: dict[int, int] = {}           # tests: id(object) -> cid
        self.digests: dict[int, tuple] = {}      # tests: cid -> an array as last sent
        self.kept: dict[int, Any] = {}           # notebook: cid -> the array last received
        self.proxies: dict[int, Any] = {}        # tests: hid -> stand-in
        self.callables: dict[int, Callable] = {}  # notebook: hid -> function
        self.hids: dict[int, int] = {}           # notebook: id(function) -> hid
        self.names: dict[int, str] = {}          # notebook: hid -> its name in messages
        self.mirrors: dict[int, tuple[int, Any]] = {}  # notebook: id(copy) -> (cid, copy)
        self.fresh: list[tuple[Any, Any]] = []   # notebook: the last message's mirrors
        self.changed: set[int] = set()           # notebook: ids of mirrors to send back

    def encode(self, value: Any) -> bytes:
        """``value`` as one message: the part count, the parts' lengths, the JSON header of
        nodes, the buffers (raises :class:`RefusedAnswer` on the notebook's side for a
        value the tests would not read)."""
        encoder = Encoder(self)
        with _collector_paused():
            root = encoder.run(value)
            header = json.dumps({"root": root, "nodes": encoder.nodes}, allow_nan=False,
                                separators=(",", ":")).encode()
        parts = [header, *encoder.buffers]
        return b"".join([struct.pack(f"<I{len(parts)}Q", len(parts), *map(len, parts)),
                         *parts])

    def send(self, value: Any) -> None:
        """Encode ``value`` and send it as one message (one write: no waiting on TCP's
        acknowledgement of a first small part)."""
        self.conn.send_bytes(self.encode(value))

    def recv(self) -> Any:
        """Receive one message and decode it; the tests refuse what is not plain data."""
        try:
            data = self.conn.recv_bytes(_LIMIT)
            (count,) = struct.unpack_from("<I", data, 0)
            if not 1 <= count < 1 << 20:
                raise RefusedAnswer("a message with a bad number of parts")
            lengths = struct.unpack_from(f"<{count}Q", data, 4)
            start = 4 + 8 * count
            if start + sum(lengths) != len(data):
                raise RefusedAnswer("a message whose parts do not add up")
            parts = []
            for length in lengths:
                parts.append(data[start:start + length])
                start += length
            with _collector_paused():
                header = json.loads(parts[0].decode("utf-8"))
                return Decoder(self, header["nodes"], parts[1:]).run(header["root"])
        except _BAD_MESSAGE as exc:
            if not self.tests:
                raise
            raise RefusedAnswer(f"a value the tests cannot read ({type(exc).__name__}: "
                                f"{' '.join(str(exc).split())[:120]})") from None

    def offer(self, fn: Callable, name: str) -> int:
        """Notebook side: a handle for ``fn`` (``name`` is how messages call it)."""
        hid = self.hids.get(id(fn))
        if hid is None:
            hid = self.hids[id(fn)] = len(self.callables) + 1
            self.callables[hid], self.names[hid] = fn, name
        return hid

    def collect(self) -> list:
        """Notebook side: the mirrors of the last message that a call changed; they go back
        with the reply (:meth:`send` encodes them with their new state)."""
        out = [obj for obj, before in self.fresh if changed(obj, before)]
        self.changed = {id(obj) for obj in out}
        return out

    def register(self, obj: Any) -> int:
        """Tests side: the id (cid) of ``obj``, kept alive as long as the wire."""
        cid = self.cids.get(id(obj))
        if cid is None:
            cid = self.cids[id(obj)] = len(self.originals) + 1
            self.originals[cid] = obj
        return cid

