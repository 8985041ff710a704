"""microconveyor-env: micropart conveyor simulator (Kogut–Etsion contact, stick–slip dynamics)
and its Gymnasium environments: ``MicroConveyor-v1`` (the conveyor on the dissertation's
chapter-4 surface, targets to 10 mm), ``MicroConveyorGoal-v1`` (the same scene with a Dict
observation and ``compute_reward``, for HER), ``MicroConveyor2D-v0`` (a grid of actuators
positioning a part in the plane) and ``MicroConveyor-v0`` (the chapter-3 predecessor, kept
unchanged).

Importing the package registers every id of :data:`.env_ids.REGISTRY` (idempotent), each with
a vector entry point to its batched env where it has one, so ``gym.make("MicroConveyor-v1")``
and ``gym.make_vec("MicroConveyor-v1", N)`` work; ``gym.make("microconveyor_env:MicroConveyor-v1")``
imports the package itself. Each env card's version history says what changed.
"""
from __future__ import annotations

__version__ = "0.3.0"

# the light module only: the envs themselves load when one is made
from .env_ids import DEFAULT_ENV_ID, FIRST_ENV_ID, register_all  # noqa: E402, F401
from .env_ids import LATEST as LATEST_ENV_ID  # noqa: E402, F401  (the newest version of the line)

ENV_ID = DEFAULT_ENV_ID   # what every command and function uses unless told

register_all()

_SUBMODULES = ("envs", "physics", "presets", "studies", "plots", "cli")


def __getattr__(name: str) -> object:
    """``microconveyor_env.envs`` (and the other subpackages) on first use, so that
    ``import microconveyor_env; help(microconveyor_env.envs.MicroConveyorEnv)`` works while the
    import itself stays light (PEP 562)."""
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
