"""Validated configuration of the line's envs, MicroConveyor-v0 and -v1 and the goal env
(defaults in ``configs/envs/MicroConveyor-v0.yaml``, a later version's beyond them in its own
``configs/envs/<id>.yaml``; SI units): a rail's config (:class:`~..rail.config.RailConfig`),
one firing per actuator."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from ...env_ids import DEFAULT_ENV_ID, REGISTRY
from ...physics.materials import ParameterError
from ..core.versions import check_env_id, config_class, scene_config
from ..rail.config import RailConfig


@dataclass(frozen=True)
class EnvConfig(RailConfig):
    """All settings of the line's envs (SI units); ``configs/envs/MicroConveyor-v0.yaml`` gives
    each field's meaning, unit and MicroConveyor-v0's value."""

    CONFIG_FILE: ClassVar[str] = "MicroConveyor-v0.yaml"

    @property
    def episode_limit(self) -> tuple[int, str]:
        """One firing per actuator: ``n_actuators`` steps at most."""
        return self.n_actuators, f"the {self.n_actuators} actuators"


def env_config(env_id: str = DEFAULT_ENV_ID, **overrides: Any) -> EnvConfig:
    """The validated config of ``gym.make(env_id, **overrides)`` (SI units) of the line's ids
    (:class:`EnvConfig`); :func:`~..core.versions.scene_config` takes every registered id."""
    if REGISTRY[check_env_id(env_id)].geometry != "line":
        raise ParameterError(f"{env_id} is not a conveyor line (its config is a "
                             f"{config_class(env_id).__name__}); use scene_config")
    config: EnvConfig = scene_config(env_id, **overrides)
    return config
