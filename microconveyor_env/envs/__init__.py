"""Gymnasium environments of the micro-conveyor, one subpackage per scene on a shared core:
:mod:`.line` (MicroConveyor-v0, -v1 and the goal env), :mod:`.positioner` (MicroPositioner-v0),
:mod:`.plane` (MicroConveyor2D-v0, -v1); :mod:`.rail` what the two scenes on a line of
actuators share; :mod:`.core` what every scene shares (the config base, the part container, the
single and batched envs, the saved part state, the reward arithmetic, the checks, the SB3
adapter of any id, and :mod:`.core.versions`: the registered ids' configs, batched envs and
scenes)."""
from .core.versions import scene_differences
from .line.config import EnvConfig, env_config
from .line.env import MicroConveyorEnv
from .line.goal import MicroConveyorGoalEnv
from .line.part_state import PartState
from .line.vector import MicroConveyorVectorEnv
from .plane.config import PlaneEnvConfig
from .plane.env import MicroConveyor2DEnv
from .plane.part_state import PlaneState
from .plane.vector import MicroConveyor2DVectorEnv
from ..env_ids import ENV_IDS, LATEST

__all__ = ["ENV_IDS", "LATEST", "EnvConfig", "MicroConveyor2DEnv", "MicroConveyor2DVectorEnv",
           "MicroConveyorEnv", "MicroConveyorGoalEnv", "MicroConveyorVectorEnv", "PartState",
           "PlaneEnvConfig", "PlaneState", "env_config", "scene_differences"]
