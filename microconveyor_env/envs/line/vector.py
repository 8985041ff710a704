"""Batched MicroConveyor-v0/v1: N parts on the line stepped together by one compiled call
(numba prange), bit-identical to N single envs (the shared machinery: :mod:`..core.vector`)."""
from __future__ import annotations

from typing import Any, ClassVar, cast

import numpy as np

from ..core.vector import MAX_ENVS, BatchedEnv
from ..rail.parts import OwnsRail, check_target
from .config import EnvConfig
from .part_state import PartState
from .state import Conveyor, conveyor_field

__all__ = ["MAX_ENVS", "MicroConveyorVectorEnv"]


class MicroConveyorVectorEnv(OwnsRail, BatchedEnv):
    """``num_envs`` independent copies of :class:`~microconveyor_env.envs.MicroConveyorEnv`.

    Same spaces, rewards and info keys as the single env (batched). Sub-env ``i`` reset with
    ``seed`` uses ``seed + i``, as ``SyncVectorEnv`` does, so both give identical rollouts.
    ``autoreset_mode``: ``NEXT_STEP`` (default, the gymnasium default: the step after a finished
    episode resets that sub-env, ignoring its action, with reward 0) or ``SAME_STEP`` (reset at
    once; the last observation and info are in ``info["final_obs"]`` / ``info["final_info"]``).
    Threads: ``num_threads`` (an EnvConfig field, also a ``make_vec`` keyword): 1 runs a serial
    loop, k > 1 numba's parallel loop with k threads, ``None`` (default) picks between the two by
    measuring them as it runs (:mod:`..core.threads`). Results are bit-identical in every case.
    ``max_episode_steps`` (``make_vec`` passes the spec's): checked to be >= ``n_actuators``.
    ``reset(options={"state": s})``: every sub-env starts from the part state ``s`` (a list:
    one per sub-env); see the single env and :mod:`.part_state`.
    Per-episode randomisation (``action_noise``, ``friction_factor_range``, ``mass_factor_range``;
    :mod:`..core.randomisation`): each part has its own row of constants and draws from streams derived
    from its own generator, so sub-env ``i`` seeded ``seed + i`` draws what the single env seeded
    ``seed + i`` draws; ``friction_factor`` / ``mass_factor`` (arrays) hold this episode's factors.
    """

    config_class: ClassVar[type] = EnvConfig
    conveyor_class = Conveyor
    sb3_info = ("is_success", "position_error_m", "outcome", "sim_time_s", "frequency_hz",
                "stroke_m", "delay_s", "friction_factor", "mass_factor")
    config: EnvConfig
    conveyor: Conveyor

    # the parts' state (arrays, one element per sub-env; written in place) and configuration
    x = conveyor_field("parts.x", "Positions [m].")
    v = conveyor_field("parts.v", "Velocities [m/s].")
    t = conveyor_field("parts.t", "Simulated times [s].")
    target = conveyor_field("parts.target", "Targets [m].")
    fired = conveyor_field("parts.fired", "Actuators fired so far (int64).")
    friction_factor = conveyor_field("friction_factor",
                                     "This episode's factor on the friction [-], per sub-env.")
    mass_factor = conveyor_field("mass_factor", "This episode's factor on the mass [-], per sub-env.")
    threads = conveyor_field("threads", "Serial or parallel, per step (:mod:`..core.threads`).")

    def set_targets(self, indices: Any, targets: Any) -> np.ndarray:
        """Give the parts of sub-envs ``indices`` new targets [m] (checked as reset's ``target``
        option) in place of the ones their reset drew; each must be at the start of its
        episode (no actuator fired). Returns every sub-env's observation (a copy). The rest of
        the episode is the one the reset drew; a training-time target distribution uses it
        (agents/rl/training/targets.py)."""
        idx = np.atleast_1d(np.asarray(indices, dtype=np.int64))
        tv = np.broadcast_to(np.asarray(targets, dtype=float), idx.shape)
        checked = []  # every target checked before any is set
        for i, t in zip(idx.tolist(), tv.tolist(), strict=True):
            if not 0 <= i < self.num_envs:
                raise IndexError(f"sub-env {i} of {self.num_envs}")
            if self.fired[i] or self.t[i]:
                raise ValueError(f"sub-env {i} is in its episode ({self.fired[i]} actuator(s) "
                                 "fired): a target can be set only at an episode's start")
            checked.append(check_target(t))
        for i, t in zip(idx.tolist(), checked, strict=True):
            self.conveyor.parts.target[i] = t
        return self._obs()

    def get_state(self, i: int) -> PartState:
        """Sub-env ``i``'s :class:`~.part_state.PartState` now (naming the env id and the
        scene; see the single env)."""
        return cast(PartState, super().get_state(i))

    def render(self) -> tuple | None:
        if self.render_mode != "rgb_array":
            return None
        from ..rail.render import render_frame

        return tuple(render_frame(self.config, self.x[i], self.target[i], int(self.fired[i]),
                                  None, self.t[i]) for i in range(self.num_envs))
