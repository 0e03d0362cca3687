"""Chapter 9 — the configuration of the paper's studies: :class:`StudyConfig` (sizes and
budgets, and the fingerprint that names its cache), the named :data:`PRESETS`, and
:class:`Run`, one trained model of a study."""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np

from minimanc import inputs, models, train, world
from minimanc.checks import check_int

TABLE_MODELS: tuple[str, ...] = ("cnn", "cnn_lstm", "rvs_g", "manc")
"""The learned comparison cases of Table I, in the paper's order."""

ABLATION_MODELS: tuple[str, ...] = ("manc", "vagn_only", "dmp_only")
"""The self-ablation of Fig. 8."""


@dataclass(frozen=True)
class StudyConfig:
    """Sizes and budgets of a study. See :data:`PRESETS` for the named ones.

    Data: ``n_train`` / ``n_tune`` / ``n_val`` scenes of one generated set
    (``data_seed``), drawn as ``raster``, a :class:`~minimanc.world.RasterConfig` (default:
    the devkit's RGB raster at 64 x 64 px; :func:`raster_text` names it; the presets draw
    :data:`LEARNER_RASTER`).
    Training (the same for every model):
    ``training``, a :class:`~minimanc.train.TrainConfig` whose ``lr``, ``seed``
    and ``subset`` each :class:`Run` replaces (its learning rate from the sweep
    ``lrs``, one of the ``n_seeds`` training seeds, its data fraction):
    ``StudyConfig(training=TrainConfig(epochs=3))``, read as ``c.training.epochs``.
    Studies: ``n_states`` of MANC in Table I,
    ``q_states``, ``fractions``, ``settings``; ``explain_scenes`` scenes get
    explainability figures. How the models learn is named by a form of :data:`FORMS`
    (:func:`with_form`). With ``training.perception_weight`` > 0 every run also learns
    the expert's perception of its training scenes as seen in its raster
    (:func:`minimanc.diagnose.perception_targets`, the auxiliary loss of
    :mod:`minimanc.train.perception`). A given dataset file
    (:func:`minimanc.studies.recorded.data_config`): ``data_file`` (its path),
    ``data_hash`` (its content hash) and ``data_source`` (``"world"``: generated,
    ``"nuscenes"``: recorded); all ``""`` when the study generates its data.

    On-policy training: ``dagger_rounds`` ≥ 1 trains every run except the learning-rate
    sweep's by DAgger (:func:`minimanc.dagger.dagger`) with the world's expert
    (:class:`minimanc.dagger.WorldTeacher`, reactive ados) on the run's training scenes,
    ``dagger_rounds`` rounds after the demonstrations (β_i = 0.5^i), at the labelled states
    behaviour cloning would use; round 0 trains ``training.epochs``, every later round
    continues from the previous one for ``round_epochs`` epochs (so the rounds together
    take about behaviour cloning's gradient steps). ``0`` (default): behaviour cloning
    (Algorithm 1). The sweeps stay behaviour cloning. On-policy, the auxiliary perception
    loss also learns what the expert perceives in the states DAgger collects
    (:func:`minimanc.diagnose.state_targets`).
    ``model``: the :class:`~minimanc.models.ModelConfig` every run starts from (default:
    the library's, the paper's models), read as ``c.model.predicate_readout``; each run
    sets its own ``n_states`` and ``setting`` and the data its ``input_shape``
    (:meth:`model_config`), so those three stay at their defaults here.
    """

    preset: str = "custom"
    n_train: int = 650
    n_tune: int = 40
    n_val: int = 200
    raster: world.RasterConfig = field(default_factory=world.RasterConfig)
    data_seed: int = 0
    training: train.TrainConfig = field(default_factory=train.TrainConfig)
    lrs: tuple[float, ...] = (1e-3, 3e-3)
    n_seeds: int = 3
    n_states: int = 6
    q_states: tuple[int, ...] = (3, 6, 9, 12)
    fractions: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0)
    settings: tuple[str, ...] = ("paper", "parity")
    table_models: tuple[str, ...] = TABLE_MODELS
    ablation_models: tuple[str, ...] = ABLATION_MODELS
    sample_models: tuple[str, ...] = TABLE_MODELS
    explain_scenes: int = 3
    data_file: str = ""
    data_hash: str = ""
    data_source: str = ""
    dagger_rounds: int = 0
    round_epochs: int = 1
    model: models.ModelConfig = field(default_factory=models.ModelConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.training, train.TrainConfig):
            raise ValueError(f"training must be a minimanc.train.TrainConfig; got "
                             f"training={self.training!r}")
        if not isinstance(self.raster, world.RasterConfig):
            raise ValueError(f"raster must be a minimanc.world.RasterConfig; got "
                             f"raster={self.raster!r}")
        for name in ("n_train", "n_tune", "n_val", "n_seeds", "n_states",
                     "explain_scenes"):
            check_int(name, getattr(self, name), 0 if name == "explain_scenes" else 1)
        if bool(self.data_file) != bool(self.data_hash) or bool(self.data_file) != bool(
                self.data_source):
            raise ValueError("data_file, data_hash and data_source are given together "
                             "(minimanc.studies.recorded.data_config); got "
                             f"data_file={self.data_file!r}, data_hash={self.data_hash!r}, "
                             f"data_source={self.data_source!r}")
        if self.n_train < 2:
            raise ValueError(f"n_train must be >= 2; got n_train={self.n_train!r}")
        if not self.lrs or any(not (np.isfinite(x) and x > 0) for x in self.lrs):
            raise ValueError(f"lrs must be positive learning rates; got lrs={self.lrs!r}")
        if not self.fractions or any(not 0 < f <= 1 for f in self.fractions):
            raise ValueError(f"fractions must lie in (0, 1]; got fractions={self.fractions!r}")
        if not self.q_states or any(int(n) != n or n < 1 for n in self.q_states):
            raise ValueError(f"q_states must be positive integers; got {self.q_states!r}")
        for s in self.settings:
            if s not in inputs.SETTINGS:
                raise ValueError(f"settings must be from {inputs.SETTINGS}; got {s!r}")
        for group in ("table_models", "ablation_models", "sample_models"):
            for mdl in getattr(self, group):
                if mdl not in models.names():
                    raise ValueError(f"{group} must hold names from {models.names()}; "
                                     f"got {mdl!r}")
        self._check_model()
        self._check_on_policy()

    def _check_model(self) -> None:
        """``model`` a ModelConfig whose per-run fields are left to the runs."""
        if not isinstance(self.model, models.ModelConfig):
            raise ValueError(f"model must be a minimanc.models.ModelConfig; got "
                             f"model={self.model!r}")
        base = models.ModelConfig()
        for name, where in (("n_states", "StudyConfig.n_states and q_states"),
                            ("setting", "StudyConfig.settings"),
                            ("input_shape", "the data")):
            if getattr(self.model, name) != getattr(base, name):
                raise ValueError(f"model.{name} is each run's (set by {where}); leave it at "
                                 f"its default, got model.{name}="
                                 f"{getattr(self.model, name)!r}")

    def model_config(self, n_states: int, setting: str) -> models.ModelConfig:
        """The :class:`~minimanc.models.ModelConfig` of a run with ``n_states`` q-states in
        ``setting``: :attr:`model` with those two (the input shape is the data's, filled in
        by :func:`minimanc.train.fit`)."""
        return replace(self.model, n_states=n_states, setting=setting)

    def _check_on_policy(self) -> None:
        """``dagger_rounds`` and ``round_epochs`` valid, and usable with the rest."""
        rounds = check_int("dagger_rounds", self.dagger_rounds, 0)
        check_int("round_epochs", self.round_epochs, 1)
        if rounds == 0:
            return
        fractions = (1.0, *self.fractions) if self.sample_models else (1.0,)
        fewest = len(train.subset_scenes(self.n_train, min(fractions), 0))
        if fewest < rounds + 1:
            raise ValueError(f"dagger_rounds={rounds} needs at least {rounds + 1} training "
                             f"scenes in every run; the smallest (n_train={self.n_train} at "
                             f"data fraction {min(fractions):g}) has {fewest}")

    @property
    def on_policy(self) -> bool:
        """Whether the study's runs (but the sweeps') train by DAgger (``dagger_rounds`` > 0)."""
        return self.dagger_rounds > 0

    def train_config(self, model: str, lr: float, seed: int, fraction: float
                     ) -> train.TrainConfig:
        """The :class:`~minimanc.train.TrainConfig` of one run: :attr:`training` with its
        ``lr``, ``seed`` and ``subset`` (``model`` is accepted for per-model rules)."""
        models.check_name(model, "model")
        return replace(self.training, lr=lr, seed=seed, subset=fraction)

    def fingerprint(self) -> str:
        """Hash of everything that changes data or training (not ``n_seeds`` or the figures).

        A given data file enters by its content hash and source (not its path); without
        one the hash is that of the configuration before the option, and so is it with
        behaviour cloning (``dagger_rounds`` 0: neither it nor ``round_epochs`` enters) and
        the library's models (:attr:`model` the default). Holds every field of
        :attr:`training` and the library's defaults of :class:`minimanc.models.ModelConfig`,
        so that a cache written by a version that trained differently is never reused.
        """
        d = asdict(self)
        for k in ("preset", "n_seeds", "explain_scenes", "data_file"):
            d.pop(k)
        for k in ("data_hash", "data_source"):
            if not d[k]:
                d.pop(k)
        if not self.on_policy:
            d.pop("dagger_rounds")
            d.pop("round_epochs")
        if self.model == models.ModelConfig():
            d.pop("model")
        d["model_defaults"] = models.ModelConfig().to_dict()
        d["default_gains"] = list(models.DEFAULT_GAINS)
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(range(self.n_seeds))


LEARNER_RASTER = world.RasterConfig(size=90, cols=64, metres_ahead=60.0, encoding="channels",
                                    route=True, history=2)
"""The learner's raster (chapter 7): binary planes of the map, the ego's route ahead and the
other vehicles at t, t−1, t−2, 60 m ahead at the devkit's 0.78 m per pixel (90 × 64 px)."""

LEARNER_MODEL = models.ModelConfig(predicate_readout="flatten", n_predicates=64,
                                   gains_input="q_p", position_lookahead=10.0,
                                   position_lookahead_time=0.0)
"""The learner's models (chapter 8): eq. 7 over the flattened features, 64 predicates, MANC's
gains over q ⊕ p (eq. 11 with the predicates beside the automaton's state) and the DMP's
position goal at a fixed 10 m along the lane target (its speed then ``≈ β_y · 10 m``, linear
in the gain, where the paper's speed-scaled goal makes it steep near ``β_y τ_y = 1``)."""

FORMS: dict[str, dict[str, Any]] = {
    "paper": {"raster": world.RasterConfig(), "dagger_rounds": 0, "model": models.ModelConfig()},
    "learner": {"raster": LEARNER_RASTER, "dagger_rounds": 10, "model": LEARNER_MODEL},
}
"""How a study's models learn, by name (:func:`with_form`): ``"paper"``, the paper's form
(the devkit's RGB raster, behaviour cloning by Algorithm 1, the library's models: eq. 7 over
the pooled features, eq. 11's ``FC(q)``); ``"learner"``, the learner's form
(:data:`LEARNER_RASTER`, DAgger with the world's expert for 10 rounds, :data:`LEARNER_MODEL`).
How long each round after the first trains (``round_epochs``) is a budget, as ``epochs``
is: each preset sets it."""


PRESETS: dict[str, StudyConfig] = {
    # the test suite: seconds, numbers meaningless
    "tiny": StudyConfig(
        preset="tiny", n_train=4, n_tune=1, n_val=2, raster=world.RasterConfig(size=32),
        training=train.TrainConfig(epochs=1, batch_size=16, max_steps_per_epoch=2, seq_len=4),
        lrs=(1e-3,), n_seeds=1, q_states=(3, 6), fractions=(0.5, 1.0), explain_scenes=1,
    ),
    # minutes on 2 cores (README): every study, one seed, one learning rate, small data; each
    # DAgger round after the first continues one epoch (most of the run's time is training)
    "quick": StudyConfig(
        preset="quick", n_train=32, n_tune=8, n_val=24,
        training=train.TrainConfig(epochs=3, batch_size=64), lrs=(1e-3,), n_seeds=1,
        q_states=(3, 6, 12), fractions=(0.5, 1.0), round_epochs=1, **FORMS["learner"],
    ),
    # three seeds, more data and epochs than "quick", and the learning-rate sweep
    "full": StudyConfig(
        preset="full", n_train=96, n_tune=16, n_val=48,
        training=train.TrainConfig(epochs=4, batch_size=64), lrs=(1e-3, 3e-3), n_seeds=3,
        round_epochs=2, **FORMS["learner"],
    ),
    # the paper's sizes: 650 training / 200 validation scenes, three seeds
    "paper": StudyConfig(
        preset="paper", n_train=650, n_tune=40, n_val=200,
        training=train.TrainConfig(epochs=6, batch_size=64), lrs=(3e-4, 1e-3, 3e-3), n_seeds=3,
        round_epochs=2, **FORMS["learner"],
    ),
}
"""Named configurations, every one but ``tiny`` in the learner's form (:data:`FORMS`;
:func:`with_form` gives the paper's): ``tiny`` (tests), ``quick`` (``--quick``), ``full``
(the default) and ``paper`` (the paper's data sizes)."""


def with_form(config: StudyConfig, form: str) -> StudyConfig:
    """``config`` with the raster, on-policy training and predicate read-out of ``form``
    (one of :data:`FORMS`); its sizes, budgets and studies unchanged."""
    if form not in FORMS:
        raise ValueError(f"form must be one of {sorted(FORMS)}; got form={form!r}")
    return replace(config, **FORMS[form])


def form_of(config: StudyConfig) -> str | None:
    """The name of the form of :data:`FORMS` that ``config`` is in, or ``None``."""
    for name, settings in FORMS.items():
        if all(getattr(config, k) == v for k, v in settings.items()):
            return name
    return None


def model_text(model: models.ModelConfig) -> str:
    """How a study's :attr:`StudyConfig.model` departs from the library's models, in words
    (``""`` for the default): ``"eq. 7 over the flattened features, 64 predicates, MANC's
    gains over q ⊕ p, the DMP's goal 10 m ahead"``, then any other field as
    ``name = value``."""
    if not isinstance(model, models.ModelConfig):
        raise ValueError(f"model must be a minimanc.models.ModelConfig; got model={model!r}")
    base = models.ModelConfig()
    words = []
    changed = [f.name for f in fields(model) if getattr(model, f.name) != getattr(base, f.name)]
    if "predicate_readout" in changed:
        read = "flattened" if model.predicate_readout == "flatten" else "pooled"
        words.append(f"eq. 7 over the {read} features")
    if "n_predicates" in changed:
        words.append(f"{model.n_predicates} predicates")
    if "gains_input" in changed:
        words.append("MANC's gains over " + " ⊕ ".join(model.gains_input.split("_")))
    if {"position_lookahead", "position_lookahead_time"} & set(changed):
        per_speed = (f" + {model.position_lookahead_time:g} s × speed"
                     if model.position_lookahead_time else "")
        words.append(f"the DMP's goal {model.position_lookahead:g} m{per_speed} ahead")
    told = {"predicate_readout", "n_predicates", "gains_input", "position_lookahead",
            "position_lookahead_time"}
    words += [f"{k} = {getattr(model, k)!r}" for k in changed if k not in told]
    return ", ".join(words)


def raster_text(raster: world.RasterConfig) -> str:
    """``raster`` in a few words, as ``table1.md`` and ``docs/reproduce.md`` name it: rows ×
    columns and the encoding (``"64×64 RGB raster (the paper's form)"``, ``"90×64 binary
    channels (route, vehicles at t, t−1, t−2), 60 m ahead"``), then the extent where it is
    not the devkit's (40 m ahead, 10 m behind, 25 m to each side)."""
    if not isinstance(raster, world.RasterConfig):
        raise ValueError(f"raster must be a minimanc.world.RasterConfig; got raster={raster!r}")
    size = f"{raster.size}×{raster.width}"
    if raster == world.RasterConfig(size=raster.size):
        return f"{size} RGB raster (the paper's form)"
    past = ["t", *(f"t−{j}" for j in range(1, raster.history + 1))]
    if raster.encoding == "rgb":
        text = f"{size} RGB raster" + (f" (history {', '.join(past)})" if raster.history else "")
    else:
        parts = ["route"] * raster.route + [f"vehicles at {', '.join(past)}"]
        text = f"{size} binary channels ({', '.join(parts)})"
    base = world.RasterConfig()
    for name, words in (("metres_ahead", "ahead"), ("metres_behind", "behind"),
                        ("metres_side", "to each side")):
        if getattr(raster, name) != getattr(base, name):
            text += f", {getattr(raster, name):g} m {words}"
    return text


def perception_text(weight: float) -> str:
    """What a study's training adds to Algorithm 1, in words: the auxiliary perception loss
    and its weight λ (``TrainConfig.perception_weight``) when ``weight`` > 0, else ``""``."""
    return f"with the auxiliary perception loss (λ = {weight:g})" if weight > 0 else ""


def dagger_text(rounds: int, round_epochs: int, swept: bool = True) -> str:
    """How a study's runs were trained when not by behaviour cloning alone, in words:
    DAgger's ``rounds`` and the ``round_epochs`` of each round after the first
    (:attr:`StudyConfig.dagger_rounds`) when ``rounds`` > 0, else ``""``; ``swept``: the
    study has a learning-rate sweep (more than one of :attr:`StudyConfig.lrs`), which
    trains by behaviour cloning."""
    if rounds <= 0:
        return ""

    def count(n: int, word: str) -> str:
        return f"{n} {word}{'s' if n != 1 else ''}"

    return (f"trained on-policy: DAgger with the world's expert, {count(rounds, 'round')}, "
            f"each after the first continuing {count(round_epochs, 'epoch')}"
            + (" (the learning-rate sweep by behaviour cloning)" if swept else ""))


def presets_table() -> str:
    """:data:`PRESETS` as a Markdown table (``docs/reproduce.md`` shows it): per preset its
    scenes, raster (:func:`raster_text`), epochs (and λ of the auxiliary perception loss
    when it is on, DAgger's rounds when the runs train on-policy: :func:`dagger_text`),
    learning rates, seeds and the q-states and data fractions of the studies."""
    lines = ["| preset | train / tune / validation scenes | BEV raster | epochs | learning rates "
             "| seeds | q-states | data fractions |", "|---|---|---|---|---|---|---|---|"]
    for name, c in PRESETS.items():
        epochs = " ".join(filter(None, (str(c.training.epochs),
                                        perception_text(c.training.perception_weight))))
        epochs = "; ".join(filter(None, (epochs, dagger_text(c.dagger_rounds, c.round_epochs,
                                                             len(c.lrs) > 1))))
        lines.append(f"| `{name}` | {c.n_train} / {c.n_tune} / {c.n_val} | "
                     f"{raster_text(c.raster)} | {epochs} | "
                     f"{', '.join(f'{x:g}' for x in c.lrs)} | "
                     f"{c.n_seeds} | {', '.join(str(n) for n in c.q_states)} | "
                     f"{', '.join(f'{f:g}' for f in c.fractions)} |")
    return "\n".join(lines)


@dataclass(frozen=True)
class Run:
    """One trained model: ``model``, information ``setting``, ``n_states``, data
    ``fraction``, training ``seed`` and learning rate ``lr``; ``on_policy``: trained by
    DAgger (:attr:`StudyConfig.dagger_rounds`) rather than behaviour cloning, a run of its
    own (its :attr:`key` ends in ``-dagger``) beside the sweep's run of the same numbers."""

    model: str
    setting: str
    n_states: int
    fraction: float
    seed: int
    lr: float
    on_policy: bool = False

    @property
    def key(self) -> str:
        return (f"{self.model}-{self.setting}-q{self.n_states}-f{round(100 * self.fraction)}"
                f"-lr{self.lr:g}-s{self.seed}" + ("-dagger" if self.on_policy else ""))


def canonical_setting(model: str, setting: str) -> str:
    """``"paper"`` when ``model`` sees the same inputs in both settings (MANC, DMP-only)."""
    spec = models.get(model)
    if inputs.visible(spec, "paper") == inputs.visible(spec, setting):
        return "paper"
    return setting


def plan(c: StudyConfig, agents: int = 2) -> dict:
    """What a study of ``c`` computes: ``{"train": Counter((model, fraction) → number of
    trainings), "sweep": the same for the learning-rate sweep's trainings alone (behaviour
    cloning; counted in ``"train"`` too), "rollouts": {"tune": n, "val": n}}`` (closed-loop
    evaluations). A sweep run
    at seed 0 and full data that wins its sweep is the Table I run of seed 0: it is
    counted once (not when the runs train on-policy, :attr:`StudyConfig.on_policy`: the
    sweeps are behaviour cloning, so that run trains again by DAgger). Table I's runs are
    driven once more per protocol of the ados beyond the first (``agents`` protocols in
    all)."""
    pairs = [(m, s) for s in c.settings for m in c.table_models]
    pairs += [(m, "paper") for m in c.ablation_models + c.sample_models]
    sweep = {(m, canonical_setting(m, s), c.n_states, 1.0, 0, lr)
             for m, s in pairs for lr in (c.lrs if len(c.lrs) > 1 else ())}
    main: set = set()

    def add(m: str, s: str, n: int, f: float) -> None:
        main.update((m, canonical_setting(m, s), n, f, sd, "best") for sd in c.seeds)

    for s in c.settings:
        for m in c.table_models:
            add(m, s, c.n_states, 1.0)
    for m in c.sample_models:
        for f in c.fractions:
            add(m, "paper", c.n_states, f)
    for n in c.q_states:
        add("manc", "paper", int(n), 1.0)
    for m in c.ablation_models:
        add(m, "paper", c.n_states, 1.0)
    tuned = {(r[0], r[1]) for r in sweep}
    shared = {r for r in main if r[4] == 0 and r[3] == 1.0 and r[2] == c.n_states
              and (r[0], r[1]) in tuned and not c.on_policy}
    trains = Counter((r[0], r[3]) for r in (main - shared) | sweep)
    table = {(m, canonical_setting(m, s), sd) for s in c.settings for m in c.table_models
             for sd in c.seeds}
    return {"train": trains, "sweep": Counter((r[0], r[3]) for r in sweep),
            "rollouts": {"tune": len(sweep), "val": len(main) + (agents - 1) * len(table)}}

