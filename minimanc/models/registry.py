"""Chapter 8 — the model registry: one :class:`ModelSpec` per controller.

A spec says everything the rest of the library asks about a model: its
``name`` and plot ``label``, its ``family`` (what its recurrent state is), what
it ``observes`` in each information setting (:mod:`minimanc.inputs` reads it),
the :class:`~minimanc.train.TrainConfig` field that sets its training ``window``,
whether it ends in the ``dmp`` head of eqs. 10–11, and the three functions that
make it: ``init`` (its parameters after the shared backbone), ``encode`` (per
frame, no recurrence) and ``head`` (one time step); what each receives and returns is
:class:`ModelSpec`'s docstring. Adding a model is one :func:`register_model` call (or
``with registered(spec):`` for a block); MANC's pieces to build one from are public
(:mod:`minimanc.models.zoo`); :func:`names` (and :func:`vagn_models`, :func:`lstm_models`,
:func:`dmp_models`), the CLI choices, the window rule of :mod:`minimanc.train` and the
plot labels follow.

The registry lives with the models (it holds their functions) and imports
only :mod:`minimanc.inputs`, for the observation keys and settings. ``inputs``
is the lower layer: it looks specs up at call time, never at import, so the
two modules do not import each other while loading.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from minimanc import inputs

__all__ = [
    "FAMILIES",
    "ModelSpec",
    "check_name",
    "dmp_models",
    "get",
    "lstm_models",
    "names",
    "observes_goal",
    "observes_structured",
    "register_model",
    "registered",
    "specs",
    "vagn_models",
]

FAMILIES: tuple[str, ...] = ("feedforward", "lstm", "vagn")
"""What a model carries from step to step: nothing, an LSTM's ``(h, c)``, vAGN's ``q``."""

WINDOWS: tuple[str | None, ...] = (None, "seq_len", "dmp_seq_len", "q_seq_len")
"""The :class:`~minimanc.train.TrainConfig` fields a window rule may name (``None``: 1 step)."""


def observes_goal(extra: tuple[str, ...] = ()) -> dict[str, tuple[str, ...]]:
    """The comparison models' observation rule.

    Parameters
    ----------
    extra : tuple of str
        Keys seen in both settings besides these (RvS-G: ``("goal_bev",)``).

    Returns
    -------
    dict
        ``{"paper": ("bev", "goal", *extra), "parity": ("bev", "goal", "lane_target",
        "motion", *extra)}``.
    """
    return {"paper": ("bev", "goal") + extra,
            "parity": ("bev", "goal", "lane_target", "motion") + extra}


def observes_structured() -> dict[str, tuple[str, ...]]:
    """The DMP models' observation rule.

    Returns
    -------
    dict
        ``("bev", "lane_target", "motion")`` in every setting.
    """
    keys = ("bev", "lane_target", "motion")
    return {s: keys for s in inputs.SETTINGS}


@dataclass(frozen=True)
class ModelSpec:
    """One controller.

    Parameters
    ----------
    name : str
        The model's name (``models.step(name, ...)``).
    label : str
        Its name in tables and figures.
    family : str
        One of :data:`FAMILIES`; decides :func:`minimanc.models.initial_state`.
    observes : mapping
        ``{setting: keys}`` for every setting of :data:`minimanc.inputs.SETTINGS`; keys
        from :data:`minimanc.inputs.KEYS`, ``"bev"`` always (the backbone reads it).
    init : callable
        ``init(rng, cfg, n_num) -> dict``: the parameters besides ``"backbone"``, drawn
        from ``rng`` after the backbone's; ``n_num`` is the length of the model's
        :func:`minimanc.inputs.numeric_features` in ``cfg.setting``. A ``"predicates"`` entry
        (a dense layer on eq. 7's read-out of ``f``, :func:`minimanc.models.zoo.predicate_layer`)
        makes the shared encoder compute eq. 7's predicates for the head.
    encode : callable
        ``encode(params, obs, f, num, cfg, eng) -> dict``: the per-frame part (no
        recurrence), run on every frame at once. ``obs`` holds the keys the model observes
        in ``cfg.setting`` (:func:`minimanc.inputs.visible`), cast to the parameters' dtype:
        ``bev`` ``(B, H, W, 3)``, ``goal`` ``(B, 3)``, ``lane_target`` ``(B, K, 2)``,
        ``motion`` ``(B, 2)``, ``goal_bev``; ``f`` ``(B, h, w, C)`` are the backbone's features
        of ``obs["bev"]`` and ``num`` ``(B, F)`` the numbers of
        :func:`minimanc.inputs.numeric_features` (``None`` when the model sees none). In a
        training window (:func:`minimanc.models.sequence`) ``B`` counts every frame of every
        window (``L·B``), except ``goal_bev`` (:data:`minimanc.inputs.SCENE_CONSTANT_KEYS`:
        one per window). Returns arrays with the frames on the first axis, or ``None``.
    head : callable
        ``head(params, enc, state, cfg, eng) -> (controls, new_state, aux)``: one time
        step. ``enc`` is what ``encode`` returned, for this step's ``B`` rows, and
        ``predicates`` ``(B, M)`` when the parameters hold ``"predicates"`` (eq. 7 through
        ``cfg.predicate_activation``); never the backbone's features (read them in
        ``encode``). In the training windows of a ``dmp`` model with ``motion_feedback``,
        ``enc["motion"]`` is the model's own controls of the previous step after the first
        (so a ``dmp`` model's ``encode`` returns ``motion``). ``state`` is the family's
        (:func:`minimanc.models.initial_state`): ``{}`` (feedforward), ``{"h", "c"}``
        ``(B, hidden)`` (lstm), ``{"q"}`` ``(B, N)`` (vagn: q' of eq. 9). Returns
        ``controls`` ``(B, 2)`` = ``[speed (m/s), yaw rate (rad/s)]``; ``new_state`` with the
        keys and shapes of ``state`` (the time loop of :func:`minimanc.models.sequence` and
        the closed loop carry it over); ``aux``, a dict of ``(B, ...)`` arrays with the same
        keys at every step: ``q`` for the vagn family and ``alpha``, ``beta`` ``(B, 2)`` for a
        ``dmp`` head are what a rollout records (:data:`minimanc.rollout.AUX_KEYS`;
        ``predicates`` is added by :func:`minimanc.models.step`, not by the head).
    ``init``, ``encode`` and ``head`` are pure functions of the engine ``eng`` (its
    ``eng.xp``, ``eng.nn``, no in-place assignment: CONTRIBUTING.md), so that a model runs
    and trains on both engines. MANC's pieces to build a variant from are the public
    functions of :mod:`minimanc.models.zoo` (its docstring registers MANC with gains
    ``FC(q ⊕ p)`` in a dozen lines).
    window : str or None
        The :class:`~minimanc.train.TrainConfig` field giving the training window length
        (``None``: one step).
    dmp : bool
        The head is the DMP head of eqs. 10–11 (``aux`` holds ``alpha``, ``beta``; the
        ``motion`` input is its initial state and may be fed back in training).
    colour : str
        Its colour in figures.
    """

    name: str
    label: str
    family: str
    observes: Mapping[str, tuple[str, ...]]
    init: Callable[..., dict]
    encode: Callable[..., dict]
    head: Callable[..., tuple]
    window: str | None = None
    dmp: bool = False
    colour: str = "#7f7f7f"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"name must be a Python identifier, got name={self.name!r}")
        if self.family not in FAMILIES:
            raise ValueError(f"family must be one of {FAMILIES}, got family={self.family!r}")
        if self.window not in WINDOWS:
            raise ValueError(f"window must be one of {WINDOWS}, got window={self.window!r}")
        obs = {}
        for setting in inputs.SETTINGS:
            if setting not in self.observes:
                raise ValueError(f"observes must give the keys of every setting "
                                 f"{inputs.SETTINGS}, got observes={dict(self.observes)!r}")
            keys = tuple(self.observes[setting])
            unknown = [k for k in keys if k not in inputs.KEYS]
            if unknown or "bev" not in keys:
                raise ValueError(f"observes[{setting!r}] must hold 'bev' and keys from "
                                 f"{inputs.KEYS}, got {keys!r}")
            if self.dmp and not {"lane_target", "motion"} <= set(keys):
                raise ValueError(f"a dmp model must observe 'lane_target' and 'motion', got "
                                 f"observes[{setting!r}]={keys!r}")
            obs[setting] = keys
        object.__setattr__(self, "observes", obs)
        for fn in ("init", "encode", "head"):
            if not callable(getattr(self, fn)):
                raise TypeError(f"{fn} must be callable, got {fn}={getattr(self, fn)!r}")


_SPECS: dict[str, ModelSpec] = {}


def register_model(spec: ModelSpec, replace: bool = False) -> ModelSpec:
    """Add a model to the registry.

    Parameters
    ----------
    spec : ModelSpec
        The model.
    replace : bool
        Replace a registered model of the same name.

    Returns
    -------
    ModelSpec
        ``spec``.

    Raises
    ------
    TypeError
        If ``spec`` is not a :class:`ModelSpec`.
    ValueError
        If its name is taken and not ``replace``.
    """
    if not isinstance(spec, ModelSpec):
        raise TypeError(f"spec must be a ModelSpec, got spec={spec!r}")
    if spec.name in _SPECS and not replace:
        raise ValueError(f"a model named {spec.name!r} is already registered "
                         "(pass replace=True to replace it)")
    _SPECS[spec.name] = spec
    return spec


@contextmanager
def registered(spec: ModelSpec) -> Iterator[ModelSpec]:
    """``with registered(spec):`` the model exists inside the block only.

    Parameters
    ----------
    spec : ModelSpec
        The model (its name must be free).

    Returns
    -------
    contextmanager
        Yields ``spec``; removes it on leaving the block.
    """
    register_model(spec)
    try:
        yield spec
    finally:
        _SPECS.pop(spec.name, None)


def names() -> tuple[str, ...]:
    """The registered model names.

    Returns
    -------
    tuple of str
        In registration order.
    """
    return tuple(_SPECS)


def vagn_models() -> tuple[str, ...]:
    """The registered models of the vAGN family (their state is q, eqs. 8–9).

    Returns
    -------
    tuple of str
        In registration order.
    """
    return tuple(s.name for s in _SPECS.values() if s.family == "vagn")


def lstm_models() -> tuple[str, ...]:
    """The registered models of the LSTM family (their state is the LSTM's ``(h, c)``).

    Returns
    -------
    tuple of str
        In registration order.
    """
    return tuple(s.name for s in _SPECS.values() if s.family == "lstm")


def dmp_models() -> tuple[str, ...]:
    """The registered models that end in the DMP head of eqs. 10–11.

    Returns
    -------
    tuple of str
        In registration order.
    """
    return tuple(s.name for s in _SPECS.values() if s.dmp)


def specs() -> tuple[ModelSpec, ...]:
    """The registered specs.

    Returns
    -------
    tuple of ModelSpec
        In registration order.
    """
    return tuple(_SPECS.values())


def check_name(name: Any, param: str = "name") -> str:
    """A registered model's name.

    Parameters
    ----------
    name : str
        The name to check.
    param : str
        The parameter name the error message uses.

    Returns
    -------
    str
        ``name``.

    Raises
    ------
    ValueError
        If no model of that name is registered.
    """
    if not isinstance(name, str) or name not in _SPECS:
        raise ValueError(f"{param} must be one of {names()}, got {param}={name!r}")
    return name


def get(name: Any, param: str = "name") -> ModelSpec:
    """The spec of a registered model.

    Parameters
    ----------
    name : str
        A registered model.
    param : str
        The parameter name an error message uses.

    Returns
    -------
    ModelSpec
    """
    return _SPECS[check_name(name, param)]
