"""The plane's batched env (MicroConveyor2D-v0, -v1): N parts on the plane stepped together by one compiled call (numba
prange), bit-identical to N single envs (the shared machinery: :mod:`..core.vector`)."""
from __future__ import annotations

from typing import ClassVar, cast

import numpy as np

from ..core.vector import MAX_ENVS, BatchedEnv
from .config import PlaneEnvConfig
from .part_state import PlaneState
from .state import PlaneConveyor

__all__ = ["MAX_ENVS", "MicroConveyor2DVectorEnv"]


class MicroConveyor2DVectorEnv(BatchedEnv):
    """``num_envs`` independent copies of :class:`~.env.MicroConveyor2DEnv`.

    Same spaces, rewards and info keys as the single env (batched; ``position_error_m`` is an
    ``(num_envs, 2)`` array). Sub-env ``i`` reset with ``seed`` uses ``seed + i``, as
    ``SyncVectorEnv`` does, so both give identical rollouts, bit for bit. ``autoreset_mode``:
    ``NEXT_STEP`` (default) or ``SAME_STEP`` (``final_obs`` / ``final_info``). ``num_threads`` (a
    config field): 1 a serial loop, k > 1 numba's parallel loop with k threads, None (default)
    chosen by measuring. ``reset(options={"target": (x, y)})``: one target [m] for every
    sub-env, or an ``(num_envs, 2)`` array; ``reset(options={"state": s})``: every sub-env
    starts from the saved part state ``s`` (a list: one per sub-env; :meth:`get_state`).
    Per-episode randomisation (``action_noise``, ``friction_factor_range``,
    ``mass_factor_range``; :mod:`..core.randomisation`): each part has its own row of constants
    and draws from streams derived from its generator, so sub-env ``i`` draws what a single env
    seeded ``seed + i`` draws; ``friction_factor`` / ``mass_factor`` (arrays) hold this
    episode's factors, also in ``infos`` when randomisation is on.
    """

    config_class: ClassVar[type] = PlaneEnvConfig
    conveyor_class = PlaneConveyor
    sb3_info = ("is_success", "position_error_m", "distance_m", "outcome", "sim_time_s",
                "actuator", "frequency_hz", "stroke_m", "delay_s", "friction_factor",
                "mass_factor")
    config: PlaneEnvConfig
    conveyor: PlaneConveyor

    # the parts' state (arrays, one element per sub-env; written in place)
    x = property(lambda self: self.conveyor.parts.x, doc="x [m] per sub-env")
    y = property(lambda self: self.conveyor.parts.y, doc="y [m] per sub-env")
    t = property(lambda self: self.conveyor.parts.t, doc="simulated times [s]")
    fired = property(lambda self: self.conveyor.parts.fired, doc="firings so far (int64)")
    target = property(lambda self: np.stack([self.conveyor.parts.tx, self.conveyor.parts.ty], 1),
                      doc="targets (num_envs, 2) [m] (a copy)")
    friction_factor = property(lambda self: self.conveyor.friction_factor,
                               doc="this episode's factor on the friction [-], per sub-env")
    mass_factor = property(lambda self: self.conveyor.mass_factor,
                           doc="this episode's factor on the mass [-], per sub-env")

    def get_state(self, i: int) -> PlaneState:
        """Sub-env ``i``'s :class:`~.part_state.PlaneState` now."""
        return cast(PlaneState, super().get_state(i))

    def render(self) -> tuple | None:
        """``rgb_array``: one frame per sub-env (the part and target now, no path)."""
        if self.render_mode != "rgb_array":
            return None
        from .render import render_plane_frame

        p = self.conveyor.parts
        return tuple(render_plane_frame(self.config, [(p.x[i], p.y[i])], (p.tx[i], p.ty[i]),
                                        int(p.fired[i]), None, p.t[i])
                     for i in range(self.num_envs))
