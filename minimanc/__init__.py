"""minimanc — the Multi-Abstractive Neural Controller rebuilt from first principles.

The chapter map (number, notebook, title and the modules each chapter builds; tutorials/,
solutions/ and exercises/ share the notebook names) is data: :mod:`minimanc.chapters`, which
``minimanc info`` prints.
"""

__version__ = "0.1.0"


# ``minimanc.engine(name)`` is the engine switch of chapter 1. Binding the function
# after the submodule is imported keeps the name pointing at the function (a later
# ``import minimanc.engine`` finds the module in ``sys.modules`` and leaves it alone).
from minimanc.engine import get_engine as engine  # noqa: E402

__all__ = ["__version__", "engine"]
