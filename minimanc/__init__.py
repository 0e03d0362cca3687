"""minimanc — the Multi-Abstractive Neural Controller rebuilt from first principles.

Chapter map (tutorials/, solutions/, exercises/ share the file names):
00 overview · 01 autodiff · 02 training · 03 dmp · 04 quaternions · 05 vagn ·
06 cam · 07 world · 08 manc · 09 behavior_cloning · 10 highway_sandbox.
"""

__version__ = "0.1.0"


def engine(name: str = "numpy"):
    """Return the engine ``name`` ("numpy" or "jax"); see :mod:`minimanc.engine`."""
    from minimanc.engine import get_engine

    return get_engine(name)
