"""The planners' view of a scene: one class per scene they serve, the plane refused with its
reason, the one robust cost, and one MPC class that takes either scene."""
import numpy as np
import pytest

from agents.mpc import MPC, MPCSettings, OneStepSettings
from agents.planning import LineScene, PositionerScene, robust_cost, scene_of
from microconveyor_env.envs.core.versions import nominal, scene_config


def test_each_scene_planners_serve_has_its_class_and_the_plane_is_refused():
    assert isinstance(scene_of(scene_config("MicroConveyor-v1")), LineScene)
    assert isinstance(scene_of(scene_config("MicroPositioner-v0")), PositionerScene)
    with pytest.raises(ValueError, match="no planner serves"):
        scene_of(scene_config("MicroConveyor2D-v0"))


def test_one_mpc_takes_either_scene_with_its_settings():
    line = MPC(nominal(scene_config("MicroConveyor-v0")))
    pos = MPC(nominal(scene_config("MicroPositioner-v0")))
    assert isinstance(line.settings, MPCSettings) and isinstance(pos.settings, OneStepSettings)
    with pytest.raises(ValueError, match="OneStepSettings"):
        MPC(nominal(scene_config("MicroPositioner-v0")), MPCSettings())


def test_the_robust_cost_caps_the_error_and_keeps_a_slope_beyond():
    tol = 10e-6
    e = np.array([0.0, tol, 10 * tol, 100 * tol, 0.0])
    c = robust_cost(e, np.array([True, True, True, True, False]), tol, miss=1e-3)
    assert c[0] == 0.0 and c[1] == pytest.approx(tol * (1 + 0.1 * np.log(2)))
    assert 10 * tol < c[2] < c[3] and c[4] == c[3]   # beyond the cap: only the tie-break grows
