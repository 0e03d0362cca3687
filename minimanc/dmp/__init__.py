"""Chapter 3 — the DMP of eq. (1): point attractor, damping ratio, step stability, forcing term.

The paper (``../shared/paper/manc.tex``) starts from the linear DMP of eq. (1),
``τ ÿ = α(β(g − y) − ẏ) + f(x)`` with the canonical system ``τ ẋ = −α_x x``
(the paper prints ``τ ẋ = α_x x``, a sign slip: the phase must decay), drops the
forcing term ``f`` and lets a network choose the gains instead (eq. 10)::

    ÿ = α(s) (β(s) (g − y) − ẏ)

With the error ``e = y − g`` this is the second-order system of eq. (12),
``ë + α ė + αβ e = 0``, whose character is set by the damping ratio of eq. (13),
``ζ = α / (2 √(αβ))``.

The paper steps the system at the data rate, ``DT = 0.5`` s. The continuous
system is stable for every α, β > 0, but its *discrete* step need not be: the
textbook gains α = 25, β = α/4 with one explicit Euler step of 0.5 s multiply
the error by −5.25 each step. This module therefore analyses both:

* the continuous system — :func:`eigenvalues`, :func:`damping_ratio`,
  :func:`classify`;
* the discrete one-step map of each integrator — :func:`step_matrix`,
  :func:`spectral_radius`, :func:`step_stable`, :func:`max_stable_alpha`;

and integrates it — :func:`step`, :func:`rollout` — with the three integrators

* ``"euler"`` (explicit):         ``y ← y + h ẏ``,  ``ẏ ← ẏ + h a(y, ẏ)``;
* ``"semi_implicit"`` (symplectic Euler, the usual DMP update, the default):
  ``ẏ ← ẏ + h a(y, ẏ)``, then ``y ← y + h ẏ`` with the *new* velocity;
* ``"rk4"`` (classical Runge–Kutta),

each repeated ``substeps`` times with ``h = dt / substeps``.

The full DMP of eq. (1) is here too, for the chapter that builds it (MANC's
head outputs gains only): the phase of the canonical system
(:func:`canonical_system`, :func:`phase`), Gaussian basis functions spaced in
phase (:func:`basis_centres`, :func:`basis_functions`), the forcing term
``f(x) = Σ ψ_i(x) w_i / Σ ψ_i(x) · x · (g − y0)`` (:func:`forcing_term`,
:class:`Forcing`), its weights fitted to one demonstration by locally weighted
regression (:func:`fit_forcing_weights`), and :func:`rollout` with
``forcing=...``, which adds the term inside the same integrators.

Learned gains (:func:`gains_from_logits`) pass network outputs through a
sigmoid into the boxes :data:`ALPHA_RANGE` × :data:`BETA_RANGE`, chosen so that
the default integrator is stable at :data:`DT` everywhere in the box (proved in
``tests/test_dmp.py``); :func:`zeta_penalty` is the auxiliary loss the paper
suggests against ζ ≈ 0.

Differentiable functions take the array namespace as ``xp`` (plain NumPy by
default, ``engine(...).xp`` to differentiate); the analysis functions are plain
NumPy. Bad input raises ``ValueError`` naming the parameter and its value; on
traced values (inside ``grad``/``jit``) the value checks are skipped.

The package has one module per part, and every name is re-exported here:
:mod:`~minimanc.dmp.params` (constants, shared checks), :mod:`~minimanc.dmp.attractor`
(eqs. 10, 12, 13), :mod:`~minimanc.dmp.stability` (the discrete step),
:mod:`~minimanc.dmp.forcing` (eq. 1's forcing term), :mod:`~minimanc.dmp.gains`
(learned gains) and :mod:`~minimanc.dmp.integrate` (:func:`step`, :func:`rollout`).
"""

from __future__ import annotations

from minimanc.dmp.attractor import (
    CRITICAL_RTOL,
    acceleration,
    classify,
    damping_ratio,
    eigenvalues,
)
from minimanc.dmp.forcing import (
    PHASE_END,
    Forcing,
    basis_centres,
    basis_functions,
    canonical_system,
    fit_forcing_weights,
    forcing_term,
    phase,
)
from minimanc.dmp.gains import gains_from_logits, logits_from_gains, zeta_penalty
from minimanc.dmp.integrate import DMPRollout, rollout, step
from minimanc.dmp.params import (
    ALPHA_RANGE,
    BETA_RANGE,
    DEFAULT_METHOD,
    DEFAULT_SUBSTEPS,
    DT,
    METHODS,
    check_gains,
)
from minimanc.dmp.stability import (
    check_step_stability,
    max_stable_alpha,
    spectral_radius,
    step_matrix,
    step_stable,
)

__all__ = [
    "ALPHA_RANGE",
    "BETA_RANGE",
    "CRITICAL_RTOL",
    "DEFAULT_METHOD",
    "DEFAULT_SUBSTEPS",
    "DT",
    "Forcing",
    "METHODS",
    "PHASE_END",
    "DMPRollout",
    "acceleration",
    "basis_centres",
    "basis_functions",
    "canonical_system",
    "fit_forcing_weights",
    "forcing_term",
    "phase",
    "classify",
    "damping_ratio",
    "eigenvalues",
    "gains_from_logits",
    "logits_from_gains",
    "max_stable_alpha",
    "rollout",
    "spectral_radius",
    "step",
    "step_matrix",
    "step_stable",
    "check_gains",
    "check_step_stability",
    "zeta_penalty",
]
