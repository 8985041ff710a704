"""Every invalid parameter gives one clear error naming the field, its value and the range."""
import math

import pytest

from microconveyor_env.physics.calibration import Calibration
from microconveyor_env.physics.materials import (ContactParams, Materials, ParameterError, Part,
                                                 Surface)
from microconveyor_env.presets import PresetError, load_preset, params_from_dict

BAD = {
    Materials: {"E1": [0, -1e9, math.nan, math.inf, "x"], "E2": [0, -2.0],
                "nu1": [-0.1, 0.5, 0.7, math.nan], "nu2": [0.5, -1],
                "hardness": [0, -1e9, math.inf]},
    Surface: {"sigma": [0, -20e-9, math.nan], "psi": [0, -2.5, math.nan],
              "beta": [0, -0.04, math.inf], "dgamma": [0, -1.0, math.nan], "eps": [0, -4e-10]},
    Part: {"mass": [0, -2e-9, math.nan], "area": [0, -1e-8]},
}
CASES = [(cls, field, v) for cls, fields in BAD.items() for field, vals in fields.items()
         for v in vals]


@pytest.mark.parametrize("cls,field,value", CASES)
def test_invalid_field_is_named_with_value_and_range(cls, field, value):
    with pytest.raises(ParameterError) as info:
        cls(**{field: value})
    msg = str(info.value)
    assert f"{cls.__name__}.{field}" in msg
    assert repr(value) in msg
    assert "must be a finite number in" in msg


def test_friction_scale_and_groups_validated():
    with pytest.raises(ParameterError, match="friction_scale"):
        ContactParams(friction_scale=0)
    with pytest.raises(ParameterError, match="surface"):
        ContactParams(surface={"sigma": 1e-8})
    with pytest.raises(ParameterError, match="Surface.sigma"):
        ContactParams().replace(surface__sigma=-1.0)


def test_calibration_targets_validated():
    with pytest.raises(ParameterError, match="pull_off_force"):
        Calibration(pull_off_force=-1e-6)
    with pytest.raises(ValueError, match="friction_load"):
        Calibration(friction_load=1e-8)


@pytest.mark.filterwarnings("ignore::microconveyor_env.presets.PresetWarning")  # partial files
def test_preset_errors_are_clear(tmp_path):
    with pytest.raises(PresetError, match="available: conveyor, feasibility, gold, ke, "):
        load_preset("no-such-preset")
    bad = tmp_path / "bad.yaml"
    bad.write_text("surface: {sigma: -1}\n")
    with pytest.raises(ParameterError, match="Surface.sigma"):
        load_preset(str(bad))
    typo = tmp_path / "typo.yaml"
    typo.write_text("surfce: {}\n")
    with pytest.raises(PresetError, match="unknown key 'surfce'"):
        load_preset(str(typo))
    with pytest.raises(ParameterError, match="surface"):
        params_from_dict({"surface": {"sigmaa": 1e-8}})
    # a typo names itself, the likely key and every valid one
    with pytest.raises(ParameterError, match=r"surface: unknown key 'dgama' \(did you mean "
                                             r"'dgamma'\?\); valid keys: beta, dgamma, eps, psi, sigma"):
        params_from_dict({"surface": {"dgama": 1.0}})


def test_former_names_still_work_with_a_deprecation_warning():
    """'seed' and 'dissertation' were the (chapter-3) preset, 'seed' the kinematics level; configs that still say so keep working."""
    import gymnasium as gym

    import microconveyor_env  # noqa: F401
    from microconveyor_env.envs import EnvConfig
    from microconveyor_env.presets import load_preset, simulator

    with pytest.warns(DeprecationWarning, match="'seed' is now called 'feasibility'"):
        assert load_preset("seed").name == "feasibility"
    with pytest.warns(DeprecationWarning, match="'dissertation' is now called 'feasibility'"):
        assert load_preset("dissertation").contact == load_preset("feasibility").contact
    with pytest.warns(DeprecationWarning, match="'seed' is now called 'reduced'"):
        assert simulator(kinematics="seed").kinematics == "reduced"
    with pytest.warns(DeprecationWarning):
        cfg = EnvConfig.from_yaml(preset="seed", kinematics="seed")
    assert cfg.kinematics == "reduced"
    with pytest.warns(DeprecationWarning):
        env = gym.make("MicroConveyor-v0", preset="seed").unwrapped
    assert env.sim.contact == load_preset("feasibility").contact


def test_an_incomplete_preset_says_what_it_leaves_to_the_defaults(tmp_path):
    from microconveyor_env.presets import PresetWarning, available_presets, load_preset

    f = tmp_path / "only_e1.yaml"
    f.write_text("materials: {E1: 1.7e+11}\n")
    with pytest.warns(PresetWarning, match=r"does not give materials.nu1, .*surface.sigma, .*"
                                           r"part.mass"):
        p = load_preset(str(f))
    assert p.contact.materials.E1 == 1.7e11
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")   # the shipped presets are complete
        for name in available_presets():
            load_preset(name)
