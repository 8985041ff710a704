"""SB3's env checker on MicroConveyorGoal-v1, exactly as the env's docstring says to call it
(and the call it warns about fails as it says, so the docstring is revisited if that changes)."""
import re
import warnings

import pytest

sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")


def _documented_snippet() -> str:
    from microconveyor_env.envs.line.goal import MicroConveyorGoalEnv

    doc = MicroConveyorGoalEnv.__doc__ or ""
    block = re.search(r"::\n\n((?:        .*\n|\n)+)", doc)
    assert block, "the docstring shows how to run SB3's checker"
    return "\n".join(line[8:] for line in block.group(1).splitlines())


def test_the_documented_check_passes_and_the_call_it_warns_about_fails_as_it_says():
    import gymnasium as gym

    import microconveyor_env  # noqa: F401

    code = _documented_snippet()
    assert 'check_env(gym.make("MicroConveyorGoal-v1").unwrapped)' in code
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # SB3's notes about goal envs and bounds
        exec(compile(code, "MicroConveyorGoalEnv docstring", "exec"), {})
        # (rl-zoo3, once imported in the same process, swaps in its PatchedTimeLimit)
        with pytest.raises(AttributeError, match="TimeLimit' object has no attribute "
                                                 "'compute_reward'"):
            sb3_checker.check_env(gym.make("MicroConveyorGoal-v1"))
