"""minimanc — the Multi-Abstractive Neural Controller rebuilt from first principles.

Chapter map (tutorials/, solutions/, exercises/ share the file names):
00 overview · 01 autodiff · 02 training · 03 dmp · 04 quaternions · 05 vagn ·
06 cam · 07 world · 08 manc · 09 behavior_cloning · 10 highway_sandbox.
"""

__version__ = "0.1.0"


# ``minimanc.engine(name)`` is the engine switch of chapter 1. Binding the function
# after the submodule is imported keeps the name pointing at the function (a later
# ``import minimanc.engine`` finds the module in ``sys.modules`` and leaves it alone).
from minimanc.engine import get_engine as engine  # noqa: E402

__all__ = ["__version__", "engine"]
