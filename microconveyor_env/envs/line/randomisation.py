"""Per-episode randomisation of the line's envs (all off by default; docs/randomisation.md). The
streams, draws and factors are every scene's, written once in :mod:`..core.randomisation`; the
line draws ``n_actuators`` rows of noise per episode (one per firing).

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

from ..core.randomisation import (  # noqa: F401  (the line's names of the shared pieces)
    FACTORS,
    INFO_KEYS,
    NOISE,
    RAND_KEY,
    apply_factors,
    draw,
    streams,
)

__all__ = ["FACTORS", "INFO_KEYS", "NOISE", "RAND_KEY", "apply_factors", "draw", "streams"]
