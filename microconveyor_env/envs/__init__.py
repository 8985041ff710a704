"""Gymnasium environments of the micro-conveyor: ``MicroConveyor-v0`` and its batched vector env."""
from .config import EnvConfig
from .conveyor import MicroConveyorEnv
from .vector import MicroConveyorVectorEnv

__all__ = ["EnvConfig", "MicroConveyorEnv", "MicroConveyorVectorEnv"]
