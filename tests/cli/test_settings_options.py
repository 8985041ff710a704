"""A command's options from its settings dataclass: flag, parser, bounds, default and help come
from the fields (their ``metadata``), and the parsed options build the dataclass; ``--help``
reads the defaults from the class, without building an instance."""
import argparse
from dataclasses import dataclass, field

import pytest

from microconveyor_env.cli import base


@dataclass(frozen=True)
class Toy:
    count_: int = field(default=8, metadata={"help": "rounds (default {default})",
                                             "flag": "--rounds", "bounds": (1, 10)})
    step: float = field(default=1e-3, metadata={"help": "step [m] (default {default})"})
    ladder: tuple = field(default=(0.0, 0.5), metadata={"help": "levels (default {default})",
                                                        "parse": lambda t: t.split(",")})
    pairs: tuple = field(default=((1e-3, 0.01),), metadata={"help": "pairs ({default})",
                                                           "parse": str})
    fast: bool = field(default=False, metadata={"help": "go fast"})
    bar: bool = field(default=True, metadata={"help": "no bar", "flag": "--no-bar"})
    name: str | None = field(default=None, metadata={"help": "a name", "metavar": "NAME"})
    hidden: int = 3   # no help: not an option

    def __post_init__(self):
        if self.count_ == 9:
            raise ValueError("count_ = 9 is refused by the settings")


def _parser(**kw):
    p = base._Parser(prog="toy")
    base.settings_options(p, Toy, **kw)
    return p


def test_options_defaults_and_help_come_from_the_fields():
    p = _parser()
    text = p.format_help()
    for shown in ("--rounds ROUNDS", "rounds (default 8)", "step [m] (default 0.001)",
                  "levels (default 0,0.5)", "pairs (0.001:0.01)", "--fast", "--no-bar",
                  "--name NAME"):
        assert shown in text, shown
    assert "--hidden" not in text
    args = p.parse_args([])
    assert base.settings_from(Toy, args) == Toy()
    args = p.parse_args(["--rounds", "3", "--step", "2e-3", "--ladder", "1,2", "--fast",
                         "--no-bar", "--name", "x"])
    assert base.settings_from(Toy, args, hidden=4) == Toy(3, 2e-3, ["1", "2"], ((1e-3, 0.01),),
                                                          True, False, "x", 4)


def test_bounds_are_checked_while_parsing_and_the_settings_check_the_rest():
    with pytest.raises(base.UsageError, match=r"--rounds: must be an integer in \[1, 10\], got 0"):
        _parser().parse_args(["--rounds", "0"])
    with pytest.raises(ValueError, match="refused by the settings"):
        base.settings_from(Toy, _parser().parse_args(["--rounds", "9"]))


def test_a_command_may_unset_a_default_and_give_its_own_parser_and_help():
    p = _parser(unset=("count_",), parse={"step": lambda t: float(t) / 1e3},
                help_={"step": "step [mm] (default {default:g} m)"})
    args = p.parse_args(["--step", "2"])
    assert args.count_ is None and args.step == 2e-3
    assert "step [mm] (default 0.001 m)" in p.format_help()
    assert base.settings_given(Toy, args) == {"step": 2e-3, "ladder": (0.0, 0.5),
                                              "pairs": ((1e-3, 0.01),), "fast": False,
                                              "bar": True}


def test_help_shows_the_settings_defaults_without_building_them(monkeypatch):
    """Every command's parser (and so ``--help``) is built with the settings classes refusing
    to be made: the defaults are read from the classes."""
    from agents.experiments.compare_settings import CompareSettings
    from agents.imitation.dagger import DaggerSettings
    from agents.mpc import MPCSettings
    from agents.rl.refinement.settings import RefineSettings
    from agents.rl.training.settings import TrainSettings
    from agents.rl.tuning.settings import TuneSettings

    def refuse(self):
        raise AssertionError(f"{type(self).__name__} built for --help")

    for cls in (CompareSettings, DaggerSettings, MPCSettings, RefineSettings, TrainSettings,
                TuneSettings):
        monkeypatch.setattr(cls, "__post_init__", refuse)
    sub = next(a for a in base.build_parser()._actions
               if isinstance(a, argparse._SubParsersAction)).choices
    place = " ".join(sub["place"].format_help().split())
    first, replan = (base.field_default(MPCSettings, n) for n in ("first_budget",
                                                                   "replan_budget"))
    assert f"(default {first},{replan})" in place
    refine = " ".join(sub["refine"].format_help().split())
    assert "(default 1000)" in refine and "correct-and-fit rounds (default 8)" in refine


@pytest.mark.parametrize("command, cls_path, fixed", [
    ("refine", "agents.rl.refinement.settings:RefineSettings", {}),
    ("train", "agents.rl.training.settings:TrainSettings", {"env_id": "MicroConveyor-v1"}),
    ("tune", "agents.rl.tuning.settings:TuneSettings", {"env_id": "MicroConveyor-v1"}),
])
def test_a_command_without_options_builds_the_settings_defaults(command, cls_path, fixed):
    import importlib

    module, name = cls_path.split(":")
    cls = getattr(importlib.import_module(module), name)
    argv = [command] + (["policy", "--out", "x"] if command == "refine" else [])
    args = base.build_parser().parse_args(argv)
    assert base.settings_from(cls, args, **fixed) == cls(**fixed)
