"""Per-episode randomisation of the line's envs (all off by default; docs/randomisation.md).

Three options of :class:`.config.EnvConfig`:

* ``action_noise`` sigma [action units]: the env fires ``clip(action + sigma * z, -1, 1)``,
  ``z`` a standard normal per component and firing (the fired f/h/d are in ``info``);
* ``friction_factor_range`` [-]: a factor drawn uniformly per episode multiplies the contact's
  friction Q(N) (static and sliding: the KE ``friction_scale``);
* ``mass_factor_range`` [-]: a factor drawn uniformly per episode multiplies the part's mass
  (inertia and weight). The contact table does not depend on the mass (only the load it is read
  at does), so the same table serves; the env checks that the heaviest part's peak load stays
  inside it.

Seed convention. Each part owns the generator the env already seeds (the single env's
``np_random``; sub-env ``i`` of the batched env: seed ``+ i``, as ``SyncVectorEnv``). The
randomisation draws come from two further streams *derived* from that generator's seed sequence
(same entropy, spawn key extended by ``(RAND_KEY, 0)`` for the episode factors and
``(RAND_KEY, 1)`` for the noise), never from the generator itself. Hence

* with randomisation off nothing is drawn and every existing stream is untouched (rollouts are
  bit-identical to the env without these options);
* with it on the start and target draws are the same as with it off, a part's factors and noise
  depend only on its seed and its episode count, and the single env seeded ``s + i`` and sub-env
  ``i`` of the batched env seeded ``s`` draw the same values;
* per episode the factor stream gives two uniforms ``(u_f, u_m)`` (factor = ``lo + (hi - lo) u``)
  whatever the ranges are, and the noise stream (when sigma > 0) ``n_actuators x 3`` standard
  normals whatever sigma is, so different perturbation levels with one seed use the same random
  numbers, scaled (common random numbers: level-to-level differences are not sampling noise).
  The noise of a whole episode is drawn at its reset; firing ``k`` uses row ``k``.
"""
from __future__ import annotations

import hashlib
from typing import TYPE_CHECKING

import numpy as np

from ...physics import forces

if TYPE_CHECKING:
    from .config import EnvConfig

RAND_KEY = 0x72616E64  # "rand": the spawn-key word of the randomisation streams
FACTORS, NOISE = 0, 1  # the two derived streams
INFO_KEYS = ("friction_factor", "mass_factor")  # in info when randomisation is on


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


def draw(cfg: EnvConfig, rngs: tuple[np.random.Generator, np.random.Generator],
         base_P: np.ndarray, P_row: np.ndarray,
         noise_row: np.ndarray | None) -> tuple[float, float]:
    """Draw one episode's (friction factor, mass factor) and execution noise of one part: fill its
    row of the per-part constants ``P_row`` (``base_P`` with the factors applied) and, when
    ``action_noise`` > 0, its ``(firings, 3)`` standard normals ``noise_row`` (else None), one row
    per firing an episode can have (``cfg.episode_limit``: the line's ``n_actuators``)."""
    u_f, u_m = rngs[FACTORS].random(2)
    (f_lo, f_hi), (m_lo, m_hi) = cfg.friction_factor_range, cfg.mass_factor_range
    ff = f_lo + (f_hi - f_lo) * float(u_f)
    mf = m_lo + (m_hi - m_lo) * float(u_m)
    apply_factors(base_P, P_row, ff, mf)
    if cfg.action_noise > 0.0:
        assert noise_row is not None
        noise_row[:] = rngs[NOISE].standard_normal((cfg.episode_limit[0], 3))
    return ff, mf


def apply_factors(base_P: np.ndarray, P_row: np.ndarray, friction_factor: float,
                  mass_factor: float) -> None:
    """Fill ``P_row`` with ``base_P`` whose friction and mass are multiplied by the factors [-]."""
    P_row[:] = base_P
    P_row[forces.I_MASS] = base_P[forces.I_MASS] * mass_factor
    P_row[forces.I_FSCALE] = base_P[forces.I_FSCALE] * friction_factor
