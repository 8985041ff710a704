"""microconveyor-env: micropart conveyor simulator (Kogut–Etsion contact, stick–slip dynamics)
and the Gymnasium environments ``MicroConveyor-v0``, ``MicroConveyor-v1`` and its goal-conditioned
variant ``MicroConveyorGoal-v1`` (Dict observation, ``compute_reward``; for HER).

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

    # the light module only: the envs themselves load when one is made
    from .env_ids import ALL_ENV_IDS, ENTRY_POINTS, ENV_IDS, PLANE_ENTRY_POINT, \
        PLANE_ENV_IDS, PLANE_MAX_FIRINGS, PLANE_VECTOR_ENTRY_POINT, VECTOR_ENTRY_POINT, \
        max_episode_steps, overrides

    for env_id in ALL_ENV_IDS:
        if env_id in registry:
            continue
        # v0 stays registered exactly as it was (kwargs {}, no TimeLimit)
        vector = VECTOR_ENTRY_POINT if env_id in ENV_IDS else None  # goal: Sync/Async envs
        register(id=env_id, entry_point=ENTRY_POINTS[env_id], vector_entry_point=vector,
                 kwargs=overrides(env_id), max_episode_steps=max_episode_steps(env_id),
                 disable_env_checker=False)
    for env_id in PLANE_ENV_IDS:  # the plane (2-D): defaults in its own config file
        if env_id not in registry:
            register(id=env_id, entry_point=PLANE_ENTRY_POINT,
                     vector_entry_point=PLANE_VECTOR_ENTRY_POINT, kwargs={},
                     max_episode_steps=PLANE_MAX_FIRINGS, disable_env_checker=False)


_register()

_SUBMODULES = ("envs", "physics", "presets", "studies", "plots", "cli")


def __getattr__(name: str) -> object:
    """``microconveyor_env.envs`` (and the other subpackages) on first use, so that
    ``import microconveyor_env; help(microconveyor_env.envs.MicroConveyorEnv)`` works while the
    import itself stays light (PEP 562)."""
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
