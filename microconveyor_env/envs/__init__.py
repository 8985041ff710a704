"""Gymnasium environments of the micro-conveyor: ``MicroConveyor-v0`` / ``-v1`` and the batched
vector env; :mod:`.versions` holds the registered versions' defaults."""
from .config import EnvConfig
from .conveyor import MicroConveyorEnv
from .part_state import PartState
from .vector import MicroConveyorVectorEnv
from .versions import ENV_IDS, LATEST, env_config, scene_differences

__all__ = ["ENV_IDS", "LATEST", "EnvConfig", "MicroConveyorEnv", "MicroConveyorVectorEnv", "PartState",
           "env_config", "scene_differences"]
