"""Gymnasium environments of the micro-conveyor, one subpackage per scene on a shared core:
:mod:`.line` (MicroConveyor-v0, -v1 and the goal env), :mod:`.plane` (MicroConveyor2D-v0) and
:mod:`.core` (the part container, the batched env, the checks, the SB3 adapter). :mod:`.versions`
holds the registered versions' defaults."""
from .line.config import EnvConfig
from .line.env import MicroConveyorEnv
from .line.goal import MicroConveyorGoalEnv
from .line.part_state import PartState
from .line.vector import MicroConveyorVectorEnv
from .plane.config import PlaneEnvConfig
from .plane.env import MicroConveyor2DEnv
from .plane.vector import MicroConveyor2DVectorEnv
from .versions import ENV_IDS, LATEST, env_config, scene_differences

__all__ = ["ENV_IDS", "LATEST", "EnvConfig", "MicroConveyor2DEnv", "MicroConveyor2DVectorEnv",
           "MicroConveyorEnv", "MicroConveyorGoalEnv", "MicroConveyorVectorEnv", "PartState",
           "PlaneEnvConfig", "env_config", "scene_differences"]
