"""Every registered env id on every command that takes one of them (``video``, ``reach``,
``optimize``, ``demo``, ``place``, ``imitate``): each pair works, or is refused with exit status 2 and exactly
one line on stderr saying why; never a traceback."""
from __future__ import annotations

import json

import pytest

from microconveyor_env.cli import main
from microconveyor_env.env_ids import REGISTRY

# command -> its cheapest run ({tmp}: a folder of the test's own)
RUNS = {
    "video": ["--policy", "shipped", "--out", "{tmp}/v.gif", "--frames-per-stroke", "1",
              "--target", "1e-3"],
    "reach": ["--targets", "1e-3", "--budget", "10", "--robust-budget", "0", "--noisy", "2"],
    "optimize": ["--target", "1e-3", "--budget", "20"],
    "demo": ["--out", "{tmp}/demo", "--targets", "1e-3", "--gif-target", "0"],
    "place": ["--target", "1e-3", "--method", "policy"],
    "imitate": ["--out", "{tmp}/dagger", "--rounds", "1", "--episodes", "2"],
}
# (command, env id) pairs refused, and a word the one line must hold
REFUSED = {(c, e): "line" for c in ("reach", "optimize")
           for e in ("MicroConveyor2D-v0", "MicroConveyor2D-v1", "MicroPositioner-v0")}
# demo and place take every id; a plane's target is a point, so one number is refused there
# (the plane through both: tests/cli/test_front_doors.py)
REFUSED.update({(c, e): w for c, w in (("demo", "x,y pairs"), ("place", "X,Y"))
                for e in ("MicroConveyor2D-v0", "MicroConveyor2D-v1")})
# imitate has a recipe for the positioner, v1 and the current plane (2D-v1)
REFUSED.update({("imitate", e): "recipe" for e in ("MicroConveyor-v0", "MicroConveyorGoal-v1",
                                                    "MicroConveyor2D-v0")})


def test_the_walk_covers_every_registered_id():
    assert set(REGISTRY) == {"MicroConveyor-v0", "MicroConveyor-v1", "MicroConveyorGoal-v1",
                             "MicroConveyor2D-v0", "MicroConveyor2D-v1", "MicroPositioner-v0"}


@pytest.mark.parametrize("env_id", sorted(REGISTRY))
@pytest.mark.parametrize("command", sorted(RUNS))
def test_command_works_on_env_or_refuses_in_one_line(command, env_id, tmp_path, capsys):
    """In process, as ``microconveyor COMMAND ... --env ID --json`` (``main`` returns the exit
    status and writes what the command line writes)."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("imageio")
    argv = [a.format(tmp=tmp_path) for a in RUNS[command]]
    status = main([command, *argv, "--env", env_id, "--json"])
    stdout, stderr = capsys.readouterr()
    if (command, env_id) in REFUSED:
        assert status == 2, stdout
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and env_id in lines[0], stderr
        assert REFUSED[command, env_id] in lines[0] and "Traceback" not in stderr
        assert json.loads(stdout)["error_type"] == "ValueError"
        return
    assert status == 0, stderr
    out = json.loads(stdout)
    assert (out["episode"] if command == "demo" else out)["env_id"] == env_id
