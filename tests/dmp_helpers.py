"""What the tests of minimanc.dmp (chapter 3) share: the engines they run on, the
hypothesis float options and the finite-difference oracle."""

from minimanc.autodiff.check import numerical_grad

ENGINES = ["numpy", "jax"]
finite = dict(allow_nan=False, allow_infinity=False)


def central_diff(f, x, eps=1e-6):
    """Central differences of a scalar function of one array (the library's oracle)."""
    return numerical_grad(f, [x], 0, eps)[0]
