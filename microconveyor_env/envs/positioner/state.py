"""N parts of MicroPositioner-v0: the state and the step that its single env (N = 1) and its
batched env share (as the line's :mod:`..line.state`, on the container every rail's scene
shares, :class:`~..rail.parts.RailParts`).

Resets draw the start and target as every rail does (:func:`..rail.parts.initial_state`) and,
with randomisation on, each part's factors and noise from streams derived from its generator
(:mod:`..core.randomisation`: one noise row per firing, ``max_firings`` rows), so the single env
seeded ``s + i`` and sub-env ``i`` of the batched env seeded ``s`` draw the same.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...physics import dynamics_kernel as kernel
from ..core.versions import scene_of
from ..rail.parts import RailParts, initial_state
from . import task
from .config import PositionerConfig
from .part_state import PositionerState, check_positioner_state
from .step import Outputs, Parts, observe_all, step_parallel, step_serial

__all__ = ["PositionerParts"]


class PositionerParts(RailParts):
    """``n`` parts on one :class:`~.config.PositionerConfig`: their state, per-episode
    randomisation and step (``parts``, ``consts``, ``action``, ``task``, ``out``: :mod:`.step`).
    ``friction_factor`` / ``mass_factor``: each part's factors this episode (1 while
    randomisation is off). Pickles (the compiled calls are rebuilt after loading)."""

    components = ("aim", "frequency", "stroke")
    step_info = (("actuator", "actuator", -1), ("frequency_hz", "frequency", 0.0),
                 ("stroke_m", "stroke", 0.0))
    config: PositionerConfig

    def __init__(self, config: PositionerConfig, n: int, num_threads: int | None = 1) -> None:
        self._start_rail(config, n, config.max_firings)  # a noise row per firing
        self.task = task.constants(config)
        z = np.zeros
        self.parts = Parts(x=z(n), t=z(n), fired=z(n, dtype=np.int64), target=z(n),
                           last_step=z(n), last_f=z(n), last_h=z(n), last_off=z(n))
        self.out = Outputs(reward=z(n), outcome=z(n, dtype=np.int64),
                           success=z(n, dtype=np.bool_), actuator=np.full(n, -1, np.int64),
                           frequency=z(n), stroke=z(n),
                           obs=z((n, task.OBS_DIM), dtype=np.float32),
                           kernel=z((n, kernel.N_OUT)))
        self.obs = self.out.obs
        self.obs_dim: int = task.OBS_DIM
        self.obs_bound: float = task.OBS_BOUND
        self._start_randomisation(config, n)
        self._start(n, num_threads)

    def compiled(self) -> tuple[Any, Any, Any, tuple[Any, ...]]:
        return step_serial, step_parallel, observe_all, (self.parts, self.task, self.out.obs)


    # ------------------------------------------------------------------ reset
    def check_state(self, state: Any) -> PositionerState:
        return check_positioner_state(state, self.config)

    def reset_part(self, i: int, rng: np.random.Generator, target: float | None = None,
                   state: PositionerState | None = None) -> None:
        """Start part ``i``'s next episode: start and target from ``rng`` (``target`` overrides
        the drawn one), its randomisation from the streams derived from ``rng``; then
        ``state``, if given, in place of all that (its randomisation fields left None keep this
        episode's draws)."""
        x0, tgt = initial_state(self.config, rng, target)
        self._draw_randomisation(i, rng)
        p = self.parts
        p.x[i], p.t[i], p.fired[i], p.target[i] = x0, 0.0, 0, tgt
        p.last_step[i] = p.last_f[i] = p.last_h[i] = p.last_off[i] = 0.0
        if state is not None:
            self._set_state(i, state)

    def get_state(self, i: int, env_id: str | None = None) -> PositionerState:
        p = self.parts
        ff, mf, noise = self._saved_randomisation(i)
        return PositionerState(float(p.x[i]), float(p.t[i]), int(p.fired[i]),
                               float(p.target[i]), float(p.last_step[i]), float(p.last_f[i]),
                               float(p.last_h[i]), float(p.last_off[i]), ff, mf, noise, env_id,
                               scene_of(self.config))

    def _set_state(self, i: int, s: PositionerState) -> None:
        p = self.parts
        p.x[i], p.t[i], p.fired[i], p.target[i] = s.position_m, s.time_s, s.fired, s.target_m
        p.last_step[i], p.last_f[i] = s.last_step_m, s.last_frequency
        p.last_h[i], p.last_off[i] = s.last_stroke, s.last_offset_m
        self._restore_randomisation(i, s)
