"""Chapter 1 — checking gradients against central differences.

``check_grads(f, *args)`` compares :func:`minimanc.autodiff.grad` with the
central difference ``(f(x + εe_i) - f(x - εe_i)) / 2ε`` for *every* element of
every (pytree) argument, and reports the worst absolute and relative errors and
where they occur. The truncation error of the central difference is O(ε²) and
its rounding error O(u/ε) (u ≈ 1e-16 in float64), so ε ≈ 1e-6 gives about ten
correct digits: check in float64.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from minimanc.autodiff.api import grad
from minimanc.tree import tree_flatten

__all__ = ["GradCheckReport", "check_grads", "numerical_grad"]


@dataclass
class GradCheckReport:
    """Outcome of :func:`check_grads` (``passed`` is False when beyond tolerance)."""

    max_abs_err: float
    max_rel_err: float
    where_abs: str
    where_rel: str
    n_checked: int
    passed: bool
    rtol: float
    atol: float

    def __str__(self) -> str:
        status = "OK" if self.passed else "FAILED"
        return (
            f"gradient check {status}: {self.n_checked} elements, "
            f"max abs error {self.max_abs_err:.3e} at {self.where_abs}, "
            f"max rel error {self.max_rel_err:.3e} at {self.where_rel} "
            f"(rtol={self.rtol:g}, atol={self.atol:g})"
        )


def _is_float_tree(x) -> bool:
    leaves, _, _ = tree_flatten(x)
    return bool(leaves) and all(
        not isinstance(v, bool | int) and np.issubdtype(np.asarray(v).dtype, np.floating)
        for v in leaves
    )


def numerical_grad(f: Callable, args: Sequence, argnum: int, eps: float = 1e-6) -> list:
    """Central-difference gradient of scalar ``f`` w.r.t. every leaf of ``args[argnum]``.

    Returns one float64 array per leaf (in :func:`tree_flatten` order).
    """
    leaves, _, rebuild = tree_flatten(args[argnum])
    base = [np.array(v, dtype=np.float64) for v in leaves]
    out = []
    for li, leaf in enumerate(base):
        g = np.zeros_like(leaf)
        for idx in np.ndindex(leaf.shape):
            vals = []
            for step in (eps, -eps):
                moved = leaf.copy()
                moved[idx] += step
                new_leaves = list(base)
                new_leaves[li] = moved
                new_args = list(args)
                new_args[argnum] = rebuild(new_leaves)
                vals.append(float(np.asarray(f(*new_args))))
            g[idx] = (vals[0] - vals[1]) / (2 * eps)
        out.append(g)
    return out


def check_grads(
    f: Callable,
    *args,
    eps: float = 1e-6,
    rtol: float = 1e-5,
    atol: float = 1e-6,
    argnums: int | Sequence[int] | None = None,
    verbose: bool = True,
) -> GradCheckReport:
    """Compare ``grad(f)`` with central differences for every element of every argument.

    ``argnums`` defaults to every positional argument that is a pytree of
    floating-point arrays (others, e.g. integer labels, are passed through).
    An element fails when ``|analytic - numeric| > atol + rtol * |numeric|``.
    Prints the report when ``verbose`` and raises ``AssertionError`` (with the
    report) on failure; returns the :class:`GradCheckReport` otherwise.
    """
    if eps <= 0:
        raise ValueError(f"eps must be positive, got eps={eps}")
    if argnums is None:
        nums = tuple(i for i, a in enumerate(args) if _is_float_tree(a))
    else:
        nums = (argnums,) if isinstance(argnums, int) else tuple(argnums)
    if not nums:
        raise ValueError("check_grads: no floating-point argument to differentiate")
    analytic = grad(f, argnums=nums)(*args)
    worst_abs, worst_rel = (-1.0, "-"), (-1.0, "-")
    n_checked, passed = 0, True
    for num, ga in zip(nums, analytic):
        _, paths, _ = tree_flatten(args[num])
        ga_leaves, _, _ = tree_flatten(ga)
        gn_leaves = numerical_grad(f, args, num, eps)
        for path, a, n in zip(paths, ga_leaves, gn_leaves):
            a = np.asarray(a, dtype=np.float64)
            err = np.abs(a - n)
            scale = np.maximum(np.abs(a), np.abs(n))
            rel = np.divide(err, scale, out=np.zeros_like(err), where=scale > 0)
            n_checked += err.size
            passed &= bool(np.all(err <= atol + rtol * np.abs(n)))
            if err.size:
                for arr, best, slot in ((err, worst_abs, 0), (rel, worst_rel, 1)):
                    i = np.unravel_index(int(np.argmax(arr)), arr.shape)
                    if arr[i] > best[0]:
                        where = f"argument {num}{path} index {tuple(int(k) for k in i)}"
                        if slot == 0:
                            worst_abs = (float(arr[i]), where)
                        else:
                            worst_rel = (float(arr[i]), where)
    report = GradCheckReport(
        max_abs_err=max(worst_abs[0], 0.0),
        max_rel_err=max(worst_rel[0], 0.0),
        where_abs=worst_abs[1],
        where_rel=worst_rel[1],
        n_checked=n_checked,
        passed=passed,
        rtol=rtol,
        atol=atol,
    )
    if verbose:
        print(report)
    if not passed:
        raise AssertionError(str(report))
    return report
