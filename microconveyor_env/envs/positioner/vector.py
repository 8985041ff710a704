"""Batched MicroPositioner-v0: N parts stepped together by one compiled call (numba prange),
bit-identical to N single envs (the shared machinery: :mod:`..core.vector`)."""
from __future__ import annotations

from typing import ClassVar, cast


from ..core.vector import BatchedEnv
from ..rail.parts import OwnsRail
from .config import PositionerConfig
from .part_state import PositionerState
from .state import PositionerParts

__all__ = ["MicroPositionerVectorEnv"]


class MicroPositionerVectorEnv(OwnsRail, BatchedEnv):
    """``num_envs`` independent copies of :class:`~.env.MicroPositionerEnv` (same spaces,
    rewards and info keys, batched). Sub-env ``i`` reset with ``seed`` uses ``seed + i``, as
    ``SyncVectorEnv`` does, so both give identical rollouts; ``autoreset_mode`` ``NEXT_STEP``
    (default) or ``SAME_STEP``; ``num_threads`` as the line's batched env;
    ``reset(options={"state": s})`` (one, or a list of one per sub-env) continues saved states;
    ``get_state(i)`` saves sub-env ``i``'s."""

    config_class: ClassVar[type] = PositionerConfig
    conveyor_class = PositionerParts
    sb3_info = ("is_success", "position_error_m", "outcome", "sim_time_s", "actuator",
                "frequency_hz", "stroke_m", "friction_factor", "mass_factor")
    config: PositionerConfig
    conveyor: PositionerParts

    x = property(lambda self: self.conveyor.parts.x, doc="Positions [m].")
    t = property(lambda self: self.conveyor.parts.t, doc="Simulated times [s].")
    target = property(lambda self: self.conveyor.parts.target, doc="Targets [m].")
    fired = property(lambda self: self.conveyor.parts.fired, doc="Firings so far (int64).")
    friction_factor = property(lambda self: self.conveyor.friction_factor,
                               doc="This episode's factor on the friction [-], per sub-env.")
    mass_factor = property(lambda self: self.conveyor.mass_factor,
                           doc="This episode's factor on the mass [-], per sub-env.")

    def get_state(self, i: int) -> PositionerState:
        """Sub-env ``i``'s :class:`~.part_state.PositionerState` now."""
        return cast(PositionerState, super().get_state(i))

    def render(self) -> tuple | None:
        if self.render_mode != "rgb_array":
            return None
        from ..rail.render import render_frame

        return tuple(render_frame(self.config, self.x[i], self.target[i], 0, None, self.t[i])
                     for i in range(self.num_envs))
