"""What a part can do on a rail, the bounds of its saved state (the line's
:class:`~..line.part_state.PartState`, the positioner's
:class:`~..positioner.part_state.PositionerState`): the speed it can reach and the positions
within ``v_max * max_time`` of the start (:func:`~..core.part_state.max_speed`)."""
from __future__ import annotations

from typing import NamedTuple

from ..core.part_state import max_speed
from .config import RailConfig


class StateBounds(NamedTuple):
    """What a part can do in a scene (:func:`state_bounds`), SI units."""

    speed_m_s: float                  # |velocity| at most
    position_m: tuple[float, float]   # (lowest, highest) position


def state_bounds(config: RailConfig) -> StateBounds:
    """The speed and positions a part can reach in ``config``'s scene (module docstring)."""
    speed = max_speed(config)
    reach = speed * config.max_time
    start = -config.start_offset
    return StateBounds(speed, (start - config.start_jitter - reach,
                               start + config.start_jitter + reach))
