"""Chapter 1 — element-wise primitives of the ``xp`` namespace, each with its VJP beside it.

Arithmetic with broadcasting (``add`` … ``logaddexp``, whose VJPs sum the
cotangent back to each argument's shape with ``unbroadcast``), ``maximum`` /
``minimum`` / ``clip`` (ties share the gradient equally, as in JAX), and the
element-wise functions (``exp``, ``log``, ``tanh``, ``arctan2`` …, ``where``).
Re-exported by :mod:`minimanc.autodiff.numpy`.
"""

from __future__ import annotations

import numpy as np

from minimanc.autodiff.boxes import unbox
from minimanc.autodiff.primitives import defvjp, primitive, through_max, unbroadcast

# ---------------------------------------------------------------------------
# Element-wise arithmetic (with broadcasting)
# ---------------------------------------------------------------------------
add = primitive(np.add)
defvjp(add, lambda g, ans, x, y: unbroadcast(x, g), lambda g, ans, x, y: unbroadcast(y, g))

subtract = primitive(np.subtract)
defvjp(subtract, lambda g, ans, x, y: unbroadcast(x, g), lambda g, ans, x, y: unbroadcast(y, -g))

multiply = primitive(np.multiply)
defvjp(
    multiply,
    lambda g, ans, x, y: unbroadcast(x, g * y),
    lambda g, ans, x, y: unbroadcast(y, g * x),
)

divide = primitive(np.divide)
defvjp(
    divide,
    lambda g, ans, x, y: unbroadcast(x, g / y),
    lambda g, ans, x, y: unbroadcast(y, -g * ans / y),
)
true_divide = divide

negative = primitive(np.negative)
defvjp(negative, lambda g, ans, x: -g)


def _pow_vjp_x(g, ans, x, y):
    with np.errstate(divide="ignore", invalid="ignore"):
        d = y * np.power(x, y - 1)
    return unbroadcast(x, g * np.where(np.equal(y, 0), 0, d))  # d/dx x**0 = 0, as in JAX


def _pow_vjp_y(g, ans, x, y):
    with np.errstate(divide="ignore", invalid="ignore"):
        return unbroadcast(y, g * ans * np.log(np.where(np.equal(x, 0), 1, x)))


power = primitive(np.power)
defvjp(power, _pow_vjp_x, _pow_vjp_y)

square = primitive(np.square)
defvjp(square, lambda g, ans, x: g * 2 * x)


remainder = primitive(np.remainder)  # x % y: d/dx = 1, d/dy = -floor(x / y), as in JAX
defvjp(
    remainder,
    lambda g, ans, x, y: unbroadcast(x, g),
    lambda g, ans, x, y: unbroadcast(y, -g * np.floor_divide(x, y)),
)
mod = remainder

logaddexp = primitive(np.logaddexp)  # log(e^x + e^y), without overflow
defvjp(
    logaddexp,
    lambda g, ans, x, y: unbroadcast(x, g * np.exp(x - ans)),
    lambda g, ans, x, y: unbroadcast(y, g * np.exp(y - ans)),
)


maximum = primitive(np.maximum)
defvjp(
    maximum,
    lambda g, ans, x, y: unbroadcast(x, through_max(g, x, y)),
    lambda g, ans, x, y: unbroadcast(y, through_max(g, y, x)),
)

minimum = primitive(np.minimum)
defvjp(
    minimum,
    lambda g, ans, x, y: unbroadcast(x, through_max(g, y, x)),
    lambda g, ans, x, y: unbroadcast(y, through_max(g, x, y)),
)


def clip(x, a_min=None, a_max=None, *, min=None, max=None):  # noqa: A002
    """``minimum(maximum(x, a_min), a_max)``, like ``jnp.clip`` (gradient included)."""
    lo = a_min if a_min is not None else min
    hi = a_max if a_max is not None else max
    if lo is not None:
        x = maximum(x, lo)
    if hi is not None:
        x = minimum(x, hi)
    return x


# ---------------------------------------------------------------------------
# Element-wise functions
# ---------------------------------------------------------------------------
exp = primitive(np.exp)
defvjp(exp, lambda g, ans, x: g * ans)

expm1 = primitive(np.expm1)
defvjp(expm1, lambda g, ans, x: g * (ans + 1))

log = primitive(np.log)
defvjp(log, lambda g, ans, x: g / x)

log1p = primitive(np.log1p)
defvjp(log1p, lambda g, ans, x: g / (1 + x))


def _sqrt_vjp(g, ans, x):
    with np.errstate(divide="ignore"):
        return g * 0.5 / ans


sqrt = primitive(np.sqrt)
defvjp(sqrt, _sqrt_vjp)

abs = primitive(np.abs)  # noqa: A001
defvjp(abs, lambda g, ans, x: g * np.sign(x))
absolute = abs

tanh = primitive(np.tanh)
defvjp(tanh, lambda g, ans, x: g * (1 - ans * ans))

sinh = primitive(np.sinh)
defvjp(sinh, lambda g, ans, x: g * np.cosh(x))

cosh = primitive(np.cosh)
defvjp(cosh, lambda g, ans, x: g * np.sinh(x))

sin = primitive(np.sin)
defvjp(sin, lambda g, ans, x: g * np.cos(x))

cos = primitive(np.cos)
defvjp(cos, lambda g, ans, x: -g * np.sin(x))

tan = primitive(np.tan)
defvjp(tan, lambda g, ans, x: g * (1 + ans * ans))

arcsin = primitive(np.arcsin)
defvjp(arcsin, lambda g, ans, x: g / np.sqrt(1 - x * x))

arccos = primitive(np.arccos)
defvjp(arccos, lambda g, ans, x: -g / np.sqrt(1 - x * x))

arctan = primitive(np.arctan)
defvjp(arctan, lambda g, ans, x: g / (1 + x * x))

arctan2 = primitive(np.arctan2)  # arctan2(y, x): the angle of the point (x, y)
defvjp(
    arctan2,
    lambda g, ans, y, x: unbroadcast(y, g * x / (x * x + y * y)),
    lambda g, ans, y, x: unbroadcast(x, -g * y / (x * x + y * y)),
)


def _where_fn(condition, x, y):
    return np.where(condition, x, y)


_where_fn.__name__ = "where"
_where = primitive(_where_fn)
defvjp(
    _where,
    None,
    lambda g, ans, c, x, y: unbroadcast(x, np.where(c, g, np.zeros_like(g))),
    lambda g, ans, c, x, y: unbroadcast(y, np.where(c, np.zeros_like(g), g)),
)


def where(condition, x=None, y=None):
    """``x`` where ``condition`` holds, else ``y`` (the condition is not differentiated)."""
    condition = unbox(condition)
    if x is None and y is None:
        return np.where(condition)
    return _where(condition, x, y)


