"""Gymnasium's ``check_env`` passes on every registered id in an install without the ``render``
extra (no pygame): an env lists the render modes this install renders, and the ``human`` mode,
asked for without pygame, is refused when the env is made, in one error naming the extra. Run in
a fresh interpreter whose ``import pygame`` fails, as it does without the extra."""
import json
import subprocess
import sys
import textwrap

import pytest

from microconveyor_env.env_ids import ALL_ENV_IDS

SCRIPT = textwrap.dedent("""
    import json, sys, warnings
    sys.modules["pygame"] = None  # import pygame fails, as without the render extra
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env
    import microconveyor_env
    from microconveyor_env.env_ids import ALL_ENV_IDS

    warnings.simplefilter("ignore")  # v0's deprecation notes, the checker's advice
    out = {}
    for env_id in ALL_ENV_IDS:
        try:
            check_env(gym.make(env_id).unwrapped)
            out[env_id] = "passed"
        except Exception as exc:
            out[env_id] = f"{type(exc).__name__}: {exc}"
    try:
        gym.make("MicroConveyor-v1", render_mode="human")
        out["human"] = "made"
    except Exception as exc:
        out["human"] = f"{type(exc).__name__}: {exc}"
    out["listed"] = gym.make("MicroConveyor-v1").unwrapped.metadata["render_modes"]
    print(json.dumps(out))
""")


# session: the test workers share out a module's tests, and a worker would build it again
# each time it comes back to the module
@pytest.fixture(scope="session")
def without_pygame():
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("env_id", ALL_ENV_IDS)
def test_check_env_passes_without_pygame(without_pygame, env_id):
    assert without_pygame[env_id] == "passed"


def test_human_mode_without_pygame_is_refused_naming_the_extra(without_pygame):
    assert without_pygame["human"].startswith("DependencyNotInstalled: ")
    assert 'pip install "microconveyor-env[render]"' in without_pygame["human"]
    assert "\n" not in without_pygame["human"]
    assert without_pygame["listed"] == ["rgb_array", "rgb_array_list"]


def test_the_class_still_names_the_human_mode():
    """gym.make reads the class's modes: with them it reaches the env (which opens the window
    or refuses in its own words) instead of wrapping it in Gymnasium's HumanRendering."""
    from microconveyor_env.envs.line.env import MicroConveyorEnv

    assert "human" in MicroConveyorEnv.metadata["render_modes"]
