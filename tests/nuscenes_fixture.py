"""The tests' old name of the package's nuScenes sample (:mod:`minimanc.world.nuscenes.sample`):
``tests/test_reproduce_data.py`` and ``benchmarks/nuscenes_import.py`` still import
``write_fixture`` from here; new code imports :func:`write_sample` from the package."""

from minimanc.world.nuscenes.sample import write_sample as write_fixture

__all__ = ["write_fixture"]
