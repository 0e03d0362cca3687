"""Chapter 1 — :func:`scan`, ``jax.lax.scan`` for this engine: a loop that is one node of the tape.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from minimanc.autodiff.boxes import FRAMES, TRACING, Box, unbox
from minimanc.autodiff.primitives import Outputs, defvjp_fwd, primitive, select_output
from minimanc.autodiff.reverse import add_cotangents, parent_cotangents
from minimanc.checks import check_int
from minimanc.tree import tree_flatten

__all__ = ["scan"]


@primitive
def _scan_node(*args):
    """The tape node of one :func:`scan` (built by :func:`scan`, never called)."""
    raise NotImplementedError("_scan_node is built by scan")  # pragma: no cover


def _is_float(value) -> bool:
    if type(value) is np.ndarray:
        return value.dtype.kind == "f"
    return np.issubdtype(np.result_type(value), np.floating)


def _scan_length(xs_vals: list, xs_paths: list[str], length: int | None) -> int:
    lengths = {}
    for v, p in zip(xs_vals, xs_paths):
        if np.ndim(v) == 0:
            raise ValueError(f"scan: every leaf of xs needs a leading (time) axis; xs{p} is "
                             f"a scalar of shape {np.shape(v)}")
        lengths[p] = np.shape(v)[0]
    if len(set(lengths.values())) > 1:
        raise ValueError(f"scan: the leaves of xs have different leading lengths {lengths}")
    if length is not None:
        try:
            length = check_int("length", length, 1)
        except ValueError as err:
            raise ValueError(f"scan: {err}") from None
    if lengths:
        n = next(iter(lengths.values()))
        if length is not None and length != n:
            raise ValueError(f"scan: length={length} but xs has leading length {n}")
        if n < 1:
            raise ValueError("scan: xs has leading length 0; scan needs at least one step")
        return n
    if length is None:
        raise ValueError("scan: xs has no arrays, so pass length=<number of steps>")
    return int(length)


def _check_carry(new, paths: list[str], new_paths: list[str], ref: list) -> None:
    if new_paths != paths:
        raise TypeError(f"scan: f must return a carry with the structure of init: init has "
                        f"leaves {paths}, f returned {new_paths}")
    for p, a, b in zip(paths, ref, new):
        vb = unbox(b)
        if type(a) is np.ndarray and (type(vb) is np.ndarray or isinstance(vb, np.generic)):
            if a.shape == vb.shape and a.dtype == vb.dtype:  # a NumPy scalar has both too
                continue
        if np.shape(a) != np.shape(vb) or np.result_type(a) != np.result_type(vb):
            raise TypeError(
                f"scan: the carry must keep its shape and dtype; at init{p} it has shape "
                f"{np.shape(a)} and dtype {np.result_type(a)} but f returned shape "
                f"{np.shape(vb)} and dtype {np.result_type(vb)} (cast it with .astype)")


def _split_step_output(out) -> tuple:
    if not (isinstance(out, (tuple, list)) and len(out) == 2):
        raise TypeError(f"scan: f(carry, x) must return a pair (new_carry, y), got "
                        f"{type(out).__name__}")
    return out


def _stack_ys(per_step: list[list]) -> list:
    return [np.stack([np.asarray(step[j]) for step in per_step])
            for j in range(len(per_step[0]))]


def scan(f: Callable, init, xs, length: int | None = None) -> tuple:
    """``jax.lax.scan`` for this engine: ``(carry, ys)`` of the loop ::

        carry = init
        for i in range(L):
            carry, y_i = f(carry, xs[i])      # xs[i]: every leaf of xs at index i
        ys = stack of the y_i along a new leading axis

    ``init``, ``xs`` and ``y`` are pytrees; the carry keeps its structure, shapes
    and dtypes (a ``TypeError`` otherwise), and ``L`` is the leading length of
    ``xs``' leaves (or ``length`` when ``xs`` is ``None``). Inside
    :func:`grad` the loop is **one node** of the tape: each step runs on a small
    tape of its own whose inputs are fresh leaves for the carry and ``x``; the
    node's VJP runs the steps' tapes in reverse order, passing the carry's
    cotangent from step to step, and sums what each step sends to traced
    values that ``f`` closes over (parameters). Derivatives with respect to
    ``init``, ``xs`` and closed-over values are those of the unrolled loop.
    """
    init_leaves, init_paths, init_rebuild = tree_flatten(init)
    xs_leaves, xs_paths, xs_rebuild = tree_flatten(xs)
    init_vals = [np.asarray(unbox(v)) for v in init_leaves]
    xs_vals = [np.asarray(unbox(v)) for v in xs_leaves]
    n = _scan_length(xs_vals, xs_paths, length)
    traced = TRACING[0] > 0 or any(isinstance(v, Box) for v in init_leaves + xs_leaves)
    if not traced:
        return _scan_plain(f, init_rebuild, init_paths, init_vals, xs_rebuild, xs_vals, n)
    carry_vals = init_vals
    xs_traced = [isinstance(v, Box) and _is_float(v._value) for v in xs_leaves]
    steps, ys_steps, y_rebuild = [], [], None
    carry_float = [_is_float(v) for v in init_vals]  # the carry keeps its dtypes (checked)
    for i in range(n):
        c_in = [Box(v) if t else v for v, t in zip(carry_vals, carry_float)]
        # only the slices of traced xs are traced: data stays plain (no tape, no VJP)
        x_in = [Box(v[i]) if t else v[i] for v, t in zip(xs_vals, xs_traced)]
        frame: dict[int, Box] = {}
        FRAMES.append(frame)
        try:
            c_out, y = _split_step_output(f(init_rebuild(c_in), xs_rebuild(x_in)))
        finally:
            FRAMES.pop()
        c_leaves, c_paths, _ = tree_flatten(c_out)
        _check_carry(c_leaves, init_paths, c_paths, init_vals)
        y_leaves, _, y_rebuild = tree_flatten(y)
        steps.append((frame, c_in, x_in, c_leaves, y_leaves))
        carry_vals = [np.asarray(unbox(v)) for v in c_leaves]
        ys_steps.append([unbox(v) for v in y_leaves])
    ys_vals = _stack_ys(ys_steps)
    step_leaves = {id(b) for s in steps for b in s[1] + s[2] if isinstance(b, Box)}
    parents = [(j, b) for j, b in enumerate(init_leaves) if isinstance(b, Box)]
    parents += [(len(init_leaves) + j, b) for j, b in enumerate(xs_leaves) if isinstance(b, Box)]
    outer: dict[int, Box] = {}  # traced values made outside the loop that f uses
    for frame, _, _, c_leaves, y_leaves in steps:
        for box in frame.values():
            for _, b in box._parents:
                key = id(b)
                if key not in frame and key not in step_leaves and key not in outer:
                    outer[key] = b
        for b in c_leaves + y_leaves:
            if isinstance(b, Box):
                key = id(b)
                if key not in frame and key not in step_leaves and key not in outer:
                    outer[key] = b
    base = len(init_leaves) + len(xs_leaves)
    parents += [(base + k, b) for k, b in enumerate(outer.values())]
    out_vals = carry_vals + ys_vals
    if not parents:  # nothing traced reaches the loop
        return init_rebuild(carry_vals), y_rebuild(ys_vals)
    res = (steps, len(carry_vals), init_vals, xs_vals, [b._value for b in outer.values()],
           list(outer), len(init_leaves), len(xs_leaves))
    node = Box(Outputs(out_vals), tuple(parents), _scan_node, (), None, res)
    if FRAMES:
        FRAMES[-1][id(node)] = node
    outs = [select_output(node, k) if _is_float(v) else v for k, v in enumerate(out_vals)]
    nc = len(carry_vals)
    return init_rebuild(outs[:nc]), y_rebuild(outs[nc:])


def _scan_plain(f, init_rebuild, init_paths, init_vals, xs_rebuild, xs_vals, n) -> tuple:
    """The loop of :func:`scan` on plain values (nothing traced)."""
    carry, ys_steps, y_rebuild = init_rebuild(init_vals), [], None
    for i in range(n):
        carry, y = _split_step_output(f(carry, xs_rebuild([v[i] for v in xs_vals])))
        c_leaves, c_paths, _ = tree_flatten(carry)
        _check_carry(c_leaves, init_paths, c_paths, init_vals)
        y_leaves, _, y_rebuild = tree_flatten(y)
        ys_steps.append(y_leaves)
    return carry, y_rebuild(_stack_ys(ys_steps))


def _accumulate(cts: dict, key: int, ct) -> None:
    cts[key] = ct if key not in cts else cts[key] + ct


def _scan_bwd(g: tuple, res: tuple) -> tuple:
    """VJP of a scan node: the steps' tapes in reverse, the carry's cotangent passed back."""
    steps, nc, init_vals, xs_vals, outer_vals, outer_ids, n_init, n_xs = res
    g_carry = list(g[:nc])
    g_ys = g[nc:]
    x_cts = [None] * n_xs
    outer_cts: dict[int, np.ndarray] = {}
    outer_set = set(outer_ids)
    for i in range(len(steps) - 1, -1, -1):
        frame, c_in, x_in, c_out, y_out = steps[i]
        # cts: boxes of this step's tape; boundary: its fresh inputs and closed-over values
        cts: dict[int, Any] = {}
        boundary: dict[int, Any] = {}
        for b, ct in zip(c_out + y_out, g_carry + [None if gy is None else gy[i]
                                                   for gy in g_ys]):
            if isinstance(b, Box) and ct is not None:
                _accumulate(cts if id(b) in frame else boundary, id(b), ct)
        # the order the boxes were made in is topological: walk it backwards
        for key in reversed(frame):
            ct = cts.pop(key, None)
            if ct is None:
                continue
            for _, parent, pct in parent_cotangents(frame[key], ct):
                pkey = id(parent)
                into = cts if pkey in frame else boundary
                prev = into.get(pkey)
                if prev is None:
                    into[pkey] = pct
                else:
                    into[pkey] = (prev + pct if type(prev) is np.ndarray
                                  else add_cotangents(prev, pct))
        g_carry = [boundary.get(id(b)) if isinstance(b, Box) else None for b in c_in]
        for j, b in enumerate(x_in):
            if isinstance(b, Box) and id(b) in boundary:
                if x_cts[j] is None:
                    x_cts[j] = np.zeros_like(xs_vals[j])
                x_cts[j][i] += boundary[id(b)]
        for key, ct in boundary.items():
            if key in outer_set:
                _accumulate(outer_cts, key, ct)
    cts_init = [np.zeros_like(v) if ct is None else ct for v, ct in zip(init_vals, g_carry)]
    cts_xs = [np.zeros_like(v) if ct is None else ct for v, ct in zip(xs_vals, x_cts)]
    cts_outer = [outer_cts.get(k, None) for k in outer_ids]
    cts_outer = [np.zeros_like(v) if ct is None else ct for v, ct in zip(outer_vals, cts_outer)]
    return tuple(cts_init + cts_xs + cts_outer)


defvjp_fwd(_scan_node, lambda *args: (None, None), _scan_bwd)
