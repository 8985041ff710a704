"""What a planner needs of a scene, for any scene it serves: the part's observed state, the
candidate firings, and batched rollouts of firings or plans from a state on the nominal (or an
identified) model (:mod:`.scene`); the cost a search scores rollouts with (:mod:`.cost`)."""
from .cost import MISS, plan_cost, robust_cost
from .scene import (LineRollouts, LineScene, PositionerRollouts, PositionerScene, Replay,
                    Rollouts, Scene, scene_of)

__all__ = ["MISS", "LineRollouts", "LineScene", "PositionerRollouts", "PositionerScene",
           "Replay", "Rollouts", "Scene", "plan_cost", "robust_cost", "scene_of"]
