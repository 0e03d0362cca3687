"""The core configurations hold only settings of the documented API: every field of
``ModelConfig``, ``TrainConfig`` and ``RasterConfig`` is documented in its class's docstring
and read by the library (by its methods or elsewhere) (no field kept for a switch that was
measured and rejected: their record is research/why_it_crashes/REPORT.md)."""

from __future__ import annotations

import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from minimanc import models, train, world

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = [models.ModelConfig, train.TrainConfig, world.RasterConfig]
FIELDS = [(cls, f.name) for cls in CONFIGS for f in dataclasses.fields(cls)]


def library_text_outside(cls: type) -> str:
    """The library's source with the class's docstring and field declarations cut out
    (its methods stay: a field its own methods read is read)."""
    own = inspect.getsource(cls)
    body = own.replace(cls.__doc__ or "", "")
    body = re.sub(r"^    \w+: [^\n]*$", "", body, flags=re.M)
    texts = []
    for path in sorted((ROOT / "minimanc").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        texts.append(text.replace(own, body) if own in text else text)
    return "\n".join(texts)


@pytest.mark.parametrize(("cls", "name"), FIELDS, ids=[f"{c.__name__}.{n}" for c, n in FIELDS])
def test_every_field_is_documented_and_read(cls: type, name: str) -> None:
    documented = re.compile(rf"``[^`]*\b{name}\b[^`]*``")
    assert documented.search(cls.__doc__ or ""), f"{cls.__name__}.{name} is not documented"
    read = re.compile(rf"\.{name}\b|[\"']{name}[\"']|\b{name}=")
    assert read.search(library_text_outside(cls)), (
        f"{cls.__name__}.{name}: nothing in minimanc reads it (a rejected switch is deleted)")
