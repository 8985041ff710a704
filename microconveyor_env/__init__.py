"""microconveyor-env: micropart conveyor simulator (Kogut–Etsion contact, stick–slip dynamics)
and the Gymnasium environment ``MicroConveyor-v0``.

Importing the package registers ``MicroConveyor-v0`` (idempotent), with a vector entry point to
the batched env, so ``gym.make("MicroConveyor-v0")`` and ``gym.make_vec("MicroConveyor-v0", N)``
work; ``gym.make("microconveyor_env:MicroConveyor-v0")`` imports the package itself.
"""
from __future__ import annotations

__version__ = "0.1.0"
ENV_ID = "MicroConveyor-v0"


def _register() -> None:
    from gymnasium.envs.registration import register, registry

    if ENV_ID in registry:
        return
    register(id=ENV_ID, entry_point="microconveyor_env.envs.conveyor:MicroConveyorEnv",
             vector_entry_point="microconveyor_env.envs.vector:MicroConveyorVectorEnv",
             disable_env_checker=False)


_register()
