"""Chapter 4 — unit quaternions: product, log and exp maps, integration, and the quaternion DMP.

Quaternions are arrays ``(..., 4)`` in the order ``(w, x, y, z)`` — the paper's
``q = [v, u]`` with scalar part ``v = w`` and vector part ``u = (x, y, z)``
(scipy's ``Rotation`` is scalar-*last*; convert with ``q[..., [1, 2, 3, 0]]``).
Every function broadcasts over leading axes and is differentiable through the
``xp`` keyword on both engines (only indexing, arithmetic and the namespace
listed in CONTRIBUTING.md are used; no in-place assignment).

Paper equations (``../shared/paper/manc.tex``):

* eq. (3) :func:`multiply` — ``(v1 + u1)(v2 + u2) = (v1 v2 − u1·u2) + (v1 u2 + v2 u1 + u1 × u2)``;
* eq. (4) :func:`log` — ``arccos(v) u/‖u‖``, computed as ``atan2(‖u‖, v) u/‖u‖``;
* eq. (5) :func:`integrate` — ``q(t + δt) = Exp(δt/2 · η/τ) * q(t)``;
* eq. (6) :func:`exp` — ``cos‖ω‖ + sin‖ω‖ ω/‖ω‖``;
* eq. (2) with learned gains, eq. (10) — :func:`quaternion_step`,
  :func:`quaternion_rollout`: ``η̇ = α (β · 2 log(g_q * q̄) − η)``, ``q̇ = ½ η * q``.

Conventions and edge cases (decided here, tested in ``tests/test_quaternion.py``):

* **Half angles.** ``log`` returns the *half*-angle vector: a rotation by θ
  about ``n`` is ``q = (cos θ/2, sin θ/2 n)`` and ``log q = θ/2 n``. The
  rotation vector (axis × angle) is ``2 log q`` (:func:`to_rotation_vector`).
* **Active rotations, world-frame composition.** ``rotate(q, v) = q v q̄``;
  ``multiply(p, q)`` applies q first, then p; ``integrate`` left-multiplies, so
  η is the angular velocity in the world frame.
* **Unit norm.** Functions that need a unit quaternion (``log``, ``rotate``,
  ``to_matrix``, ``to_axis_angle``, ``to_yaw``, ``integrate``,
  ``orientation_error``, the DMP) normalise their input. On concrete NumPy
  input they first check it: the zero quaternion raises ``ValueError``, and so
  does a norm further than :func:`unit_tolerance` of its dtype from 1 (a sign
  of a bug, not of rounding: a few float64 or float32 roundings are accepted).
  On traced values (inside ``grad``/``jit``) no check is possible; they are
  normalised silently. ``multiply``, ``conjugate`` and ``exp`` are
  plain algebra and accept any input.
* **Sign.** ``q`` and ``−q`` are the same rotation. ``log`` is eq. (4) as
  written — angle ``atan2(‖u‖, w) ∈ [0, π]`` — so ``exp(log q) = q`` exactly
  (not merely up to sign). The choice of the shorter way round is made where it
  matters: :func:`orientation_error`, :func:`to_axis_angle` and
  :func:`to_rotation_vector` use the representative with ``w ≥ 0``.
* **log at q = −1** (a 2π rotation in the double cover) is undefined: every
  ``π n`` is a valid answer. Concrete input raises ``ValueError``; on traced
  values the result is the meaningless ``≈ 0``. :func:`orientation_error` never
  hits it (it flips to ``w ≥ 0`` first).
* **exp of ‖ω‖ ≥ π** is computed as written and is a valid unit quaternion, but
  the map is no longer one-to-one: ``log(exp ω) = ω − 2π ω/‖ω‖`` for
  π < ‖ω‖ < 2π, and ``‖ω‖ = π`` gives −1. Only ‖ω‖ < π round-trips.
* **Gradients at the identity.** ``log`` at ``u = 0`` and ``exp`` at ``ω = 0``
  use a series branch selected with the double-``where`` trick (the unused
  branch is fed a safe value), so gradients are finite and exact there: the
  Jacobian of ``log`` at the identity is ``I`` and that of ``exp`` is ``[0; I]``.

Modules: :mod:`~minimanc.quaternion.algebra` (validation, eqs. 3–6, the orientation
error), :mod:`~minimanc.quaternion.rotations` (conversions), :mod:`~minimanc.quaternion.dmp`
(the quaternion DMP).
"""

from __future__ import annotations

from minimanc.quaternion.algebra import (
    conjugate,
    exp,
    identity,
    integrate,
    log,
    multiply,
    normalize,
    orientation_error,
    unit_tolerance,
)
from minimanc.quaternion.dmp import (
    QuaternionRollout,
    quaternion_rollout,
    quaternion_step,
)
from minimanc.quaternion.rotations import (
    from_axis_angle,
    from_rotation_vector,
    from_yaw,
    rotate,
    to_axis_angle,
    to_matrix,
    to_rotation_vector,
    to_yaw,
)

__all__ = [
    "QuaternionRollout",
    "conjugate",
    "exp",
    "from_axis_angle",
    "from_rotation_vector",
    "from_yaw",
    "identity",
    "integrate",
    "log",
    "multiply",
    "normalize",
    "orientation_error",
    "quaternion_rollout",
    "quaternion_step",
    "rotate",
    "to_axis_angle",
    "to_matrix",
    "to_rotation_vector",
    "to_yaw",
    "unit_tolerance",
]

