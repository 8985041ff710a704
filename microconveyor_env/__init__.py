"""microconveyor-env: micropart conveyor simulator (Kogut–Etsion contact, stick–slip dynamics)
and the Gymnasium environments ``MicroConveyor-v0`` and ``MicroConveyor-v1``.

Importing the package registers both (idempotent), each with a vector entry point to the batched
env, so ``gym.make("MicroConveyor-v1")`` and ``gym.make_vec("MicroConveyor-v1", N)`` work;
``gym.make("microconveyor_env:MicroConveyor-v1")`` imports the package itself. v1 is v0's task on
the dissertation's chapter-4 surface (the env card's version history says what changed).
"""
from __future__ import annotations

__version__ = "0.2.0"
ENV_ID = "MicroConveyor-v0"  # the first version (kept: v0 is unchanged)
LATEST_ENV_ID = "MicroConveyor-v1"


def _register() -> None:
    from gymnasium.envs.registration import register, registry

    from .envs.versions import ENV_IDS, max_episode_steps, registered_kwargs

    for env_id in ENV_IDS:
        if env_id in registry:
            continue
        # v0 stays registered exactly as it was (no TimeLimit: its episodes end by themselves)
        steps = None if env_id == ENV_ID else max_episode_steps(env_id)
        register(id=env_id, entry_point="microconveyor_env.envs.conveyor:MicroConveyorEnv",
                 vector_entry_point="microconveyor_env.envs.vector:MicroConveyorVectorEnv",
                 kwargs=registered_kwargs(env_id), max_episode_steps=steps,
                 disable_env_checker=False)


_register()
