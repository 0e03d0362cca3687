"""Hypothesis settings and shape strategies shared by the tests of minimanc.autodiff
(chapter 1): small shapes (sides 1 to 3, up to three dimensions) keep every example cheap."""

import hypothesis.extra.numpy as hnp
from hypothesis import settings
from hypothesis import strategies as st

SETTINGS = settings(max_examples=25, deadline=None)
seeds = st.integers(0, 2**32 - 1)
shapes = hnp.array_shapes(min_dims=0, max_dims=3, min_side=1, max_side=3)
pairs = hnp.mutually_broadcastable_shapes(num_shapes=2, min_dims=0, max_dims=3, max_side=3)
