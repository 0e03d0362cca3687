"""The dataset the tests of minimanc.world's dataset (chapter 7) share."""

from minimanc import world

N = 40


def generate_test_dataset() -> world.Dataset:
    """``N`` scenes of seed 5, generated in this process (``workers=1``)."""
    return world.generate(N, seed=5, workers=1)
