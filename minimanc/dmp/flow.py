"""Chapter 3 — one step of eq. (10) as one differentiable function: the sub-steps and their VJP.

A step of ``dt`` seconds runs ``n`` sub-steps of ``h = dt / n`` of one of the
integrators of :data:`~minimanc.dmp.params.METHODS` on the state ``(y, ẏ)``
with the acceleration of eq. (10), ``a = α (β (g − y) − ẏ) + F`` (``F`` the
forcing acceleration of eq. 1 divided by ``τ``, zero without forcing).

For fixed gains a sub-step is linear in ``(y, ẏ, g, F)``, and the gains enter
bilinearly, through ``α·(β (g − y) − ẏ)``. The reverse pass therefore runs the
sub-steps backwards with the transposed linear map, and each evaluation of the
acceleration at a stage state ``(y_s, ẏ_s)`` with cotangent ``ā`` adds

* ``ā · (β (g − y_s) − ẏ_s)`` to ``ᾱ``, ``ā · α (g − y_s)`` to ``β̄``,
* ``ā · αβ`` to ``ḡ`` and ``ā`` to the forcing value's cotangent,
* ``−ā·αβ`` to ``ȳ_s`` and ``−ā·α`` to the stage velocity's.

:data:`flow` is built with an engine's ``custom_vjp`` (``jax.custom_vjp``'s API,
:attr:`minimanc.engine.Engine.custom_vjp`): on the NumPy engine the whole step is
one node of the tape instead of ~8 per sub-step, and on JAX the same forward and
backward are compiled. The forward, backward and sub-step use arithmetic only, so
they run on NumPy and JAX arrays alike.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from minimanc.dmp.attractor import acceleration

__all__ = ["coefficients", "flow", "flow_backward", "flow_for", "flow_forward", "force_times",
           "substep"]


def coefficients(alpha: Any, beta: Any, h: float) -> tuple[Any, Any]:
    """``(1 − hα, hαβ)``: with them one Euler update of the velocity under eq. (10) is
    ``ẏ + h a = (1 − hα) ẏ + hαβ (g − y) + h F``.

    Parameters
    ----------
    alpha, beta : array or float
        Gains of eq. (10).
    h : float
        Sub-step length in seconds.

    Returns
    -------
    p, hab : array, shape broadcast(alpha, beta).shape
    """
    return 1.0 - h * alpha, h * (alpha * beta)


def substep(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, h: float, method: str,
            f0: Any = None, f_mid: Any = None, f1: Any = None,
            coef: tuple[Any, Any] | None = None) -> tuple[Any, Any]:
    """One sub-step of length ``h`` of ``method``; ``f0``, ``f_mid``, ``f1`` are the forcing
    accelerations at the start, the middle and the end of the sub-step (``None``: none).

    * ``"euler"``: ``y ← y + h ẏ``, ``ẏ ← ẏ + h a(y, ẏ)``;
    * ``"semi_implicit"``: ``ẏ ← ẏ + h a(y, ẏ)``, then ``y ← y + h ẏ`` (new ẏ);
    * ``"rk4"``: classical Runge–Kutta on ``(y, ẏ)`` (uses all three forcing values).

    Parameters
    ----------
    y, dy : array, shape (..., D)
        Position and velocity at the start of the sub-step.
    goal, alpha, beta : array or float
        Goal and gains of eq. (10), broadcasting against ``y``.
    h : float
        Sub-step length in seconds.
    method : str
        One of :data:`~minimanc.dmp.params.METHODS`.
    f0, f_mid, f1 : array or None
        Forcing accelerations (eq. 1 divided by τ) broadcasting against ``y``.
    coef : tuple, optional
        :func:`coefficients` of ``(alpha, beta, h)``, computed once per step.

    Returns
    -------
    y_next, dy_next : array, shape broadcast of the inputs
    """
    if method == "rk4":
        k1y, k1v = dy, acceleration(y, dy, goal, alpha, beta, f0)
        y2, v2 = y + 0.5 * h * k1y, dy + 0.5 * h * k1v
        k2y, k2v = v2, acceleration(y2, v2, goal, alpha, beta, f_mid)
        y3, v3 = y + 0.5 * h * k2y, dy + 0.5 * h * k2v
        k3y, k3v = v3, acceleration(y3, v3, goal, alpha, beta, f_mid)
        y4, v4 = y + h * k3y, dy + h * k3v
        k4y, k4v = v4, acceleration(y4, v4, goal, alpha, beta, f1)
        return (
            y + (h / 6.0) * (k1y + 2.0 * k2y + 2.0 * k3y + k4y),
            dy + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
        )
    p, hab = coefficients(alpha, beta, h) if coef is None else coef
    dy_new = p * dy + hab * (goal - y)  # ẏ + h α (β (g − y) − ẏ)
    if f0 is not None:
        dy_new = dy_new + h * f0
    if method == "euler":
        return y + h * dy, dy_new
    return y + h * dy_new, dy_new


def force_times(h: float, method: str, n: int) -> list[float]:
    """The times in ``[0, n h]`` at which a step evaluates the forcing term, in order.

    ``j h`` for each sub-step ``j < n`` (explicit and semi-implicit Euler); with
    RK4 ``j h``, ``j h + h/2`` and ``j h + h`` (start, middle and end of each).

    Parameters
    ----------
    h : float
        Sub-step length in seconds.
    method : str
        One of :data:`~minimanc.dmp.params.METHODS`.
    n : int
        Sub-steps per step.

    Returns
    -------
    list of float
        ``n`` times (``3 n`` with RK4).
    """
    if method == "rk4":
        return [t for j in range(n) for t in (j * h, j * h + 0.5 * h, j * h + h)]
    return [j * h for j in range(n)]


def _forces(forces: Any, method: str, j: int) -> tuple[Any, Any, Any]:
    """``(f0, f_mid, f1)`` of sub-step ``j`` from the values at :func:`force_times`."""
    if forces is None:
        return None, None, None
    if method == "rk4":
        return forces[3 * j], forces[3 * j + 1], forces[3 * j + 2]
    return forces[j], None, None


def _flow_plain(y, dy, goal, alpha, beta, forces, dt, method, n):
    """``n`` sub-steps of :func:`substep` from ``(y, dy)``; ``forces`` as in :func:`_forces`."""
    h = dt / n
    coef = None if method == "rk4" else coefficients(alpha, beta, h)
    y_j, v_j = y, dy
    for j in range(n):
        y_j, v_j = substep(y_j, v_j, goal, alpha, beta, h, method, *_forces(forces, method, j),
                           coef=coef)
    return y_j, v_j, (v_j - dy) / dt


def flow_forward(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, forces: Any, dt: float,
                 method: str, n: int) -> tuple[tuple[Any, Any, Any], tuple]:
    """The forward half of :func:`flow_for`'s VJP: ``((y_next, dy_next, ddy), residuals)``.

    Public so that a larger function with its own VJP (the DMP head,
    :mod:`minimanc.models.head_vjp`) can run a DMP step inside its forward and
    hand the residuals to :func:`flow_backward` in its backward. Arguments as in
    :func:`flow` (``dt`` concrete).

    Parameters
    ----------
    y, dy : array, shape (..., D)
        State at the start of the step.
    goal, alpha, beta : array or float
        Goal and gains of eq. (10), broadcasting against ``y``.
    forces : list of array or None
        Forcing accelerations at :func:`force_times` (``None``: eq. 10 alone).
    dt : float
        Step length in seconds.
    method : str
        One of :data:`~minimanc.dmp.params.METHODS`.
    n : int
        Sub-steps per step.

    Returns
    -------
    outputs : tuple
        ``(y_next, dy_next, ddy)`` as :func:`flow` returns them.
    residuals : tuple
        What :func:`flow_backward` needs.
    """
    h = dt / n
    coef = None if method == "rk4" else coefficients(alpha, beta, h)
    ys, vs = [], []
    y_j, v_j = y, dy
    if forces is None and method == "semi_implicit" and type(y) is np.ndarray:
        p, hab = coef  # substep's arithmetic, in its order, without its calls
        for _ in range(n):
            ys.append(y_j)
            vs.append(v_j)
            v_j = p * v_j + hab * (goal - y_j)
            y_j = y_j + h * v_j
    else:
        for j in range(n):
            ys.append(y_j)
            vs.append(v_j)
            y_j, v_j = substep(y_j, v_j, goal, alpha, beta, h, method,
                               *_forces(forces, method, j), coef=coef)
    # the inputs themselves are kept for the shapes and dtypes of their cotangents
    return (y_j, v_j, (v_j - dy) / dt), (ys, vs, coef, y, dy, goal, alpha, beta, forces)


def _sum_to(x: Any, g: Any) -> Any:
    """The cotangent ``g`` summed over the axes along which ``x`` was broadcast."""
    shape = tuple(getattr(x, "shape", ()))
    if tuple(g.shape) != shape:
        extra = g.ndim - len(shape)
        if extra > 0:
            g = g.sum(axis=tuple(range(extra)))
        axes = tuple(i for i, s in enumerate(shape) if s == 1 and g.shape[i] != 1)
        if axes:
            g = g.sum(axis=axes, keepdims=True)
    dtype = getattr(x, "dtype", None)
    if dtype is not None and g.dtype != dtype:
        g = g.astype(dtype)
    return g


def _acc_back(ga, ab, alpha, gy, gv):
    """Cotangents of a stage state from that of the acceleration evaluated there."""
    return gy - ab * ga, gv - alpha * ga


def _moments(ws: list, ys: list, vs: list) -> tuple[Any, Any, Any]:
    """``(Σ w_k, Σ w_k y_k, Σ w_k v_k)`` (sequential sums: the arrays are small)."""
    s_a, s_y, s_v = ws[0], ws[0] * ys[0], ws[0] * vs[0]
    for w, y, v in zip(ws[1:], ys[1:], vs[1:]):
        s_a = s_a + w
        s_y = s_y + w * y
        s_v = s_v + w * v
    return s_a, s_y, s_v


def flow_backward(dt: float, method: str, n: int, res: tuple, g: tuple) -> tuple:
    """The backward half of :func:`flow_for`'s VJP (module docstring).

    Parameters
    ----------
    dt, method, n
        As given to :func:`flow_forward`.
    res : tuple
        The residuals :func:`flow_forward` returned.
    g : tuple of array
        Cotangents of ``(y_next, dy_next, ddy)``.

    Returns
    -------
    tuple
        Cotangents of ``(y, dy, goal, alpha, beta, forces)``, each of its argument's shape
        (``None`` for ``forces=None``).
    """
    ys, vs, coef, y0, dy0, goal, alpha, beta, forces = res
    h = dt / n
    gy, gv, g_ddy = g
    g_ddy = g_ddy / dt  # ddy = (ẏ_n − ẏ_0) / dt
    gv = gv + g_ddy
    g_forces = None if forces is None else [None] * len(forces)
    if method == "rk4":
        ab = alpha * beta
        records = []  # (cotangent of an acceleration, stage position, stage velocity, force k)
        for j in range(n - 1, -1, -1):
            gy, gv = _rk4_back(gy, gv, ys[j], vs[j], goal, alpha, beta, ab, h, j, forces,
                               records)
        s_a, s_y, s_v = _moments(*[[r[i] for r in records] for i in range(3)])
        if forces is not None:
            for ga_k, _, _, k in records:
                g_forces[k] = ga_k if g_forces[k] is None else g_forces[k] + ga_k
        g_goal, s_e = ab * s_a, goal * s_a - s_y
        g_alpha, g_beta = beta * s_e - s_v, alpha * s_e
    else:
        # the velocity update ẏ' = p ẏ + hab (g − y) + h F is linear: run its transpose
        p, hab = coef
        if _same_numpy_shapes(gy, gv, p, hab, ys[0], vs[0], goal, alpha, beta,
                              *(forces or ())):  # NumPy, one shape: stack the sub-steps
            gvs = np.empty((n,) + gv.shape, dtype=np.result_type(gy, gv, p, hab))
            gy, gv = _transpose_linear(method, h, p, hab, gy, gv, gvs)
            s_a = gvs.sum(axis=0)  # the sums of _moments, one reduction each
            s_y = (gvs * np.stack(ys)).sum(axis=0)
            s_v = (gvs * np.stack(vs)).sum(axis=0)
        else:
            gvs = [None] * n  # cotangent of each sub-step's new velocity: ā = h · it
            gy, gv = _transpose_linear(method, h, p, hab, gy, gv, gvs)
            s_a, s_y, s_v = _moments(gvs, ys, vs)
        if forces is not None:
            g_forces = [h * gk for gk in gvs]
        s_e = goal * s_a - s_y  # Σ ā (g − y_j) / h
        g_goal = hab * s_a
        g_alpha = h * (beta * s_e - s_v)
        g_beta = (h * alpha) * s_e
    g_f = None if forces is None else type(forces)(
        _sum_to(f, gk) for f, gk in zip(forces, g_forces))
    return (_sum_to(y0, gy), _sum_to(dy0, gv - g_ddy), _sum_to(goal, g_goal),
            _sum_to(alpha, g_alpha), _sum_to(beta, g_beta), g_f)


def _same_numpy_shapes(*arrays: Any) -> bool:
    """True when every argument is a NumPy array and all have one shape."""
    first = arrays[0]
    if type(first) is not np.ndarray:
        return False
    shape = first.shape
    return all(type(a) is np.ndarray and a.shape == shape for a in arrays[1:])


def _transpose_linear(method, h, p, hab, gy, gv, out):
    """The transposed sub-steps of the Euler methods, last to first: ``out[j]`` receives the
    cotangent of sub-step ``j``'s new velocity; returns the cotangents of ``(y, ẏ)``."""
    for j in range(len(out) - 1, -1, -1):
        if method == "semi_implicit":
            gv = gv + h * gy  # y' = y + h ẏ'
            out[j] = gv
            gy, gv = gy - hab * gv, p * gv
        else:
            out[j] = gv
            gy, gv = gy - hab * gv, p * gv + h * gy
    return gy, gv


def _rk4_back(gy, gv, y, v, goal, alpha, beta, ab, h, j, forces, records):
    """Reverse of one RK4 sub-step (:func:`substep`), recording its four accelerations."""
    f0, f_mid, f1 = _forces(forces, method="rk4", j=j)
    k1v = acceleration(y, v, goal, alpha, beta, f0)
    v2 = v + 0.5 * h * k1v
    y2 = y + 0.5 * h * v
    k2v = acceleration(y2, v2, goal, alpha, beta, f_mid)
    y3, v3 = y + 0.5 * h * v2, v + 0.5 * h * k2v
    k3v = acceleration(y3, v3, goal, alpha, beta, f_mid)
    y4, v4 = y + h * v3, v + h * k3v
    c1, c2 = h / 6.0, h / 3.0
    g_v1, g_v2, g_v3, g_v4 = c1 * gy, c2 * gy, c2 * gy, c1 * gy  # y' = y + Σ c_i v_i
    g_k1, g_k2, g_k3, g_k4 = c1 * gv, c2 * gv, c2 * gv, c1 * gv  # ẏ' = ẏ + Σ c_i k_i
    gy_out, gv_out = gy, gv
    # stage 4: k4 = a(y4, v4); y4 = y + h v3, v4 = v + h k3
    records.append((g_k4, y4, v4, 3 * j + 2))
    g_y4, g_v4 = _acc_back(g_k4, ab, alpha, 0.0, g_v4)
    gy_out, g_v3 = gy_out + g_y4, g_v3 + h * g_y4
    gv_out, g_k3 = gv_out + g_v4, g_k3 + h * g_v4
    # stage 3: k3 = a(y3, v3); y3 = y + h/2 v2, v3 = v + h/2 k2
    records.append((g_k3, y3, v3, 3 * j + 1))
    g_y3, g_v3 = _acc_back(g_k3, ab, alpha, 0.0, g_v3)
    gy_out, g_v2 = gy_out + g_y3, g_v2 + 0.5 * h * g_y3
    gv_out, g_k2 = gv_out + g_v3, g_k2 + 0.5 * h * g_v3
    # stage 2: k2 = a(y2, v2); y2 = y + h/2 v, v2 = v + h/2 k1
    records.append((g_k2, y2, v2, 3 * j + 1))
    g_y2, g_v2 = _acc_back(g_k2, ab, alpha, 0.0, g_v2)
    gy_out, g_v1 = gy_out + g_y2, g_v1 + 0.5 * h * g_y2
    gv_out, g_k1 = gv_out + g_v2, g_k1 + 0.5 * h * g_v2
    # stage 1: k1 = a(y, v), v1 = v
    records.append((g_k1, y, v, 3 * j))
    gy_out, gv_out = _acc_back(g_k1, ab, alpha, gy_out, gv_out + g_v1)
    return gy_out, gv_out


@functools.cache
def flow_for(eng: Any) -> Any:
    """The step's sub-steps as one function with its VJP, built by ``eng.custom_vjp``.

    ``flow_for(eng)(y, dy, goal, alpha, beta, forces, dt, method, n)`` returns
    ``(y_next, dy_next, ddy)`` after ``n`` sub-steps of length ``h = dt / n``
    (``dt`` concrete), ``ddy = (dy_next − dy) / dt``;
    ``forces`` is ``None`` or a list (or tuple) of the forcing accelerations at
    :func:`force_times`. The arguments broadcast as in :func:`substep`.
    """
    f = eng.custom_vjp(_flow_plain, nondiff_argnums=(6, 7, 8))
    f.defvjp(flow_forward, flow_backward)
    return f


def flow(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, forces: Any, dt: Any,
         method: str, n: int) -> tuple[Any, Any, Any]:
    """:func:`substep` ``n`` times with ``h = dt / n``: ``(y_next, dy_next, ddy)``.

    No custom VJP: any engine differentiates it operation by operation (with a
    traced ``dt`` too); it is the reference the VJP of :func:`flow_for` is tested
    against.

    Parameters
    ----------
    y, dy : array, shape (..., D)
        State at the start of the step.
    goal, alpha, beta : array or float
        Goal and gains of eq. (10), broadcasting against ``y``.
    forces : list of array or None
        Forcing accelerations at :func:`force_times` (``None``: eq. 10 alone).
    dt : float
        Step length in seconds (may be traced).
    method : str
        One of :data:`~minimanc.dmp.params.METHODS`.
    n : int
        Sub-steps per step.

    Returns
    -------
    y_next, dy_next, ddy : array, shape broadcast of the inputs
    """
    return _flow_plain(y, dy, goal, alpha, beta, forces, dt, method, n)
