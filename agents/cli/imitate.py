"""The ``microconveyor imitate`` command: train a policy by DAgger from a model-based expert
(:mod:`agents.imitation.dagger`; the recipe of each env id in ``configs/dagger.yml``)."""
from __future__ import annotations

import argparse
import sys

from microconveyor_env.cli.base import command, emit, settings_given, settings_options

from .args import add_env_args, env_kwargs_of


def _imitate_args(p: argparse.ArgumentParser) -> None:
    from ..imitation.dagger import DaggerSettings

    p.add_argument("--out", default="runs/dagger", help="policy folder to write")
    settings_options(p, DaggerSettings, ["seed", "rounds", "episodes", "seed_policy", "requests"],
                     unset=("rounds", "episodes", "seed_policy", "requests"),
                     parse={"requests": float})
    add_env_args(p, what=" (MicroConveyor-v1: the staged expert built from the simulator alone, "
                         "or with --seed-policy that policy's firings with its last re-aimed on "
                         "the model; MicroPositioner-v0: the one-step "
                         "model-based search, trained under per-episode randomisation; "
                         "MicroConveyor2D-v1: the plane's one-step search on its firing map, "
                         "under v1's randomisation; other ids are refused; --env-kwargs are "
                         "added to the recipe's)")


@command("imitate", "train a policy by DAgger: a network that imitates a model-based expert on "
                    "the states it visits itself; written as a policy folder that loads as data",
         _imitate_args)
def cmd_imitate(args: argparse.Namespace) -> None:
    from ..imitation.dagger import DaggerSettings, recipe

    base = recipe(args.env)
    given = settings_given(DaggerSettings, args)   # the options given; the recipe's otherwise
    s = recipe(args.env, env_kwargs={**base.env_kwargs, **env_kwargs_of(args)}, **given)
    s.config()   # before any work: refuses a seed policy where the scene's expert takes none
    say = (lambda line: print(line, file=sys.stderr)) if args.json else print
    from ..imitation.dagger import dagger

    meta = dagger(args.out, s, progress=say,
                  command="microconveyor imitate " + " ".join(sys.argv[2:]))
    last = meta["rounds"][-1]
    emit(args, {"policy": args.out, "env_id": meta["env_id"], "seed": meta["seed"],
                "steps": meta["steps"], "wall_time_s": meta["wall_time_s"],
                "last_round": last},
         f"wrote {args.out}: {meta['steps']:,} env firings in {meta['wall_time_s'] / 60:.1f} min; "
         f"last round {last['success_rate']:.0%} within the tolerance, median "
         f"{last['median_abs_error_m'] * 1e6:.1f} µm (evaluate it: microconveyor evaluate "
         f"--policy {args.out})")
