"""Per-episode randomisation every scene shares (all off by default; docs/randomisation.md): the
derived random streams, the draws of one episode, the factors applied to a part's physics row,
and the bounds of the three options (a saved state's randomisation fields are checked by
:func:`.randomised_state.check_saved`).

Three options of a scene's config (the line's :class:`~..line.config.EnvConfig`, the plane's
:class:`~..plane.config.PlaneEnvConfig`):

* ``action_noise`` sigma [action units]: the env fires ``clip(a + sigma * z, -1, 1)`` for each
  firing component ``a`` (frequency, stroke, delay), ``z`` a standard normal per component and
  firing;
* ``friction_factor_range`` [-]: a factor drawn uniformly per episode multiplies the contact's
  friction Q(N) (static and sliding: the KE ``friction_scale``);
* ``mass_factor_range`` [-]: a factor drawn uniformly per episode multiplies the part's mass
  (inertia and weight); the contact table does not depend on the mass, only the load it is read
  at, so the same table serves (each env checks the heaviest part's peak load against it).

Seed convention. Each part owns the generator the env already seeds (the single env's
``np_random``; sub-env ``i`` of a batched env: seed ``+ i``, as ``SyncVectorEnv``). The draws come
from two further streams *derived* from that generator's seed sequence (same entropy, spawn key
extended by ``(RAND_KEY, 0)`` for the episode factors and ``(RAND_KEY, 1)`` for the noise), never
from the generator itself. Hence

* with randomisation off nothing is drawn and every existing stream is untouched (rollouts are
  bit-identical to the env without these options);
* with it on the start and target draws are the same as with it off, a part's factors and noise
  depend only on its seed and its episode count, and the single env seeded ``s + i`` and sub-env
  ``i`` of the batched env seeded ``s`` draw the same values;
* per episode the factor stream gives two uniforms ``(u_f, u_m)`` (factor = ``lo + (hi - lo) u``)
  whatever the ranges are, and the noise stream (when sigma > 0) a whole episode's standard
  normals (one row of 3 per firing the episode can have) whatever sigma is, so different
  perturbation levels with one seed use the same random numbers, scaled (common random numbers).
  Firing ``k`` uses row ``k``.
"""
from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from ...physics import forces

RAND_KEY = 0x72616E64  # "rand": the spawn-key word of the randomisation streams
FACTORS, NOISE = 0, 1  # the two derived streams
INFO_KEYS = ("friction_factor", "mass_factor")  # in info when randomisation is on
NOISE_COMPONENTS = 3   # the firing's components that take execution noise (f, h, delay)
# sigma of the execution noise, in action units (the action box is [-1, 1], so sigma = 1 already
# spreads a firing over the whole box); the per-episode friction and mass factors within an order
# of magnitude of the preset (beyond it, make a preset)
MAX_ACTION_NOISE = 1.0
FACTOR_BOUNDS = (0.1, 10.0)
# the config checks of the three options (SceneConfig._check_ranges / _check_pairs entries)
NOISE_RANGE = {"action_noise": (0.0, MAX_ACTION_NOISE, False, "action units")}
FACTOR_PAIRS = {"friction_factor_range": (*FACTOR_BOUNDS, "-"),
                "mass_factor_range": (*FACTOR_BOUNDS, "-")}
# numpy's standard normals never reach 12.23 (P(|z| > 13) = 1.2e-38): a saved draw beyond is not one
NOISE_BOUND = 13.0


class Randomised(Protocol):
    """What the draws read of a config."""

    @property
    def action_noise(self) -> float: ...
    @property
    def friction_factor_range(self) -> tuple: ...
    @property
    def mass_factor_range(self) -> tuple: ...


def is_randomised(cfg: Randomised) -> bool:
    """Whether any per-episode randomisation is on (noise > 0 or a factor range not (1, 1))."""
    return (cfg.action_noise > 0.0 or tuple(cfg.friction_factor_range) != (1.0, 1.0)
            or tuple(cfg.mass_factor_range) != (1.0, 1.0))


def streams(rng: np.random.Generator) -> tuple[np.random.Generator, np.random.Generator]:
    """(factor stream, noise stream) derived from ``rng``'s seed sequence, without drawing from
    ``rng``. A generator built without a seed sequence falls back to a hash of its state."""
    ss = rng.bit_generator.seed_seq
    if isinstance(ss, np.random.SeedSequence):
        entropy, key, pool = ss.entropy, tuple(ss.spawn_key), ss.pool_size
    else:  # e.g. a bit generator restored from a state dict
        digest = hashlib.sha256(repr(rng.bit_generator.state).encode()).digest()
        entropy, key, pool = int.from_bytes(digest[:16], "little"), (), 4
    return tuple(np.random.Generator(np.random.PCG64(np.random.SeedSequence(  # type: ignore[return-value]
        entropy, spawn_key=key + (RAND_KEY, j), pool_size=pool))) for j in (FACTORS, NOISE))


def _affine_is_uniform() -> bool:
    """Whether ``Generator.uniform(lo, hi)`` is ``lo + (hi - lo) * Generator.random()`` bit for
    bit with this numpy (it is where numpy's C code rounds the product before the sum, as on
    x86-64; a compiler that fuses them into one multiply-add would differ in the last bit)."""
    for lo, hi in ((0.5e-3, 3.0e-3), (-1.0, 1.0), (0.1, 10.0), (-2.5e-3, 7.25e-3)):
        a, b = (np.random.Generator(np.random.PCG64(1234)) for _ in range(2))
        if not np.array_equal(a.uniform(lo, hi, 2048), lo + (hi - lo) * b.random(2048)):
            return False
    return True


# whether a uniform draw may be written lo + (hi - lo) * u from a standard uniform u (measured at
# import): a third of the cost of Generator.uniform on a scalar, and batches of parts can share
# the arithmetic
AFFINE_UNIFORM: bool = _affine_is_uniform()


def uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    """``rng.uniform(lo, hi)`` bit for bit, drawing the same number from ``rng``: the scalar
    draw of every reset's start and target."""
    if AFFINE_UNIFORM:
        return lo + (hi - lo) * rng.random()
    return float(rng.uniform(lo, hi))


def draw(cfg: Randomised, rngs: tuple[np.random.Generator, np.random.Generator],
         base_P: np.ndarray, P_row: np.ndarray,
         noise_row: np.ndarray | None) -> tuple[float, float]:
    """Draw one episode's (friction factor, mass factor) and execution noise of one part: fill its
    row of the per-part constants ``P_row`` (``base_P`` with the factors applied) and, when
    ``action_noise`` > 0, its standard normals ``noise_row`` (one row of 3 per firing the episode
    can have; else None)."""
    u_f, u_m = rngs[FACTORS].random(2)
    (f_lo, f_hi), (m_lo, m_hi) = cfg.friction_factor_range, cfg.mass_factor_range
    ff = f_lo + (f_hi - f_lo) * float(u_f)
    mf = m_lo + (m_hi - m_lo) * float(u_m)
    apply_factors(base_P, P_row, ff, mf)
    if cfg.action_noise > 0.0:
        assert noise_row is not None
        noise_row[:] = rngs[NOISE].standard_normal(noise_row.shape)
    return ff, mf


def draw_many(cfg: Randomised, streams: Sequence[tuple[np.random.Generator, np.random.Generator]],
              base_P: np.ndarray, P: np.ndarray, rows: np.ndarray,
              noise: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`draw` for the parts ``rows`` (an index array) at once, part ``rows[k]`` from its
    ``streams[k]``: the same numbers as one :func:`draw` per part, written into those rows of
    ``P`` and, when ``action_noise`` > 0, of ``noise`` (n, rows of 3, 3); returns the
    (friction factors, mass factors) of those parts."""
    fill = noise if cfg.action_noise > 0.0 else None
    pairs = []
    for i, s in zip(rows.tolist(), streams, strict=True):
        uniform_01 = s[FACTORS].random
        pairs.append((uniform_01(), uniform_01()))  # random(2)'s two numbers, cheaper as scalars
        if fill is not None:
            s[NOISE].standard_normal(out=fill[i])
    u = np.array(pairs, dtype=float).reshape(-1, 2)
    (f_lo, f_hi), (m_lo, m_hi) = cfg.friction_factor_range, cfg.mass_factor_range
    ff = f_lo + (f_hi - f_lo) * u[:, 0]
    mf = m_lo + (m_hi - m_lo) * u[:, 1]
    P[rows] = base_P
    P[rows, forces.I_MASS] = base_P[forces.I_MASS] * mf
    P[rows, forces.I_FSCALE] = base_P[forces.I_FSCALE] * ff
    return ff, mf


def apply_factors(base_P: np.ndarray, P_row: np.ndarray, friction_factor: float,
                  mass_factor: float) -> None:
    """Fill ``P_row`` with ``base_P`` whose friction and mass are multiplied by the factors [-]."""
    P_row[:] = base_P
    P_row[forces.I_MASS] = base_P[forces.I_MASS] * mass_factor
    P_row[forces.I_FSCALE] = base_P[forces.I_FSCALE] * friction_factor
