"""The ``microconveyor imitate`` command: train a policy by DAgger from the model-based expert
(:mod:`agents.imitation.dagger`) on MicroPositioner-v0."""
from __future__ import annotations

import argparse
import sys

from microconveyor_env.cli.base import command, count, emit

from .args import add_env_args, env_kwargs_of


def _imitate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="runs/dagger", help="policy folder to write")
    p.add_argument("--seed", type=count(0, 2**31 - 1), default=0, help="training seed")
    p.add_argument("--rounds", type=count(1, 1000), default=10,
                   help="DAgger rounds (round 0: the expert acts; later: the policy)")
    p.add_argument("--episodes", type=count(1, 100000), default=256,
                   help="episodes per round, played at once on the batched env")
    add_env_args(p, default=None,
                 default_text="MicroPositioner-v0: the expert plans a positioner's firings, so "
                              "the conveyors, MicroConveyor-v1 among them, are refused",
                 what=" (--env-kwargs replace the training's randomisation: action_noise "
                      "3e-3, friction and mass factors in [0.95, 1.05])")


@command("imitate", "train a policy by DAgger: a network that imitates the one-step model-based "
                    "controller on the states it visits itself, under per-episode "
                    "randomisation; written as a policy folder that loads as data",
         _imitate_args)
def cmd_imitate(args: argparse.Namespace) -> None:
    from ..imitation.dagger import TRAIN_KWARGS, DaggerSettings, dagger

    kwargs = {**TRAIN_KWARGS, **env_kwargs_of(args)}
    s = DaggerSettings(env_id=args.env or "MicroPositioner-v0", env_kwargs=kwargs, seed=args.seed, rounds=args.rounds,
                       episodes=args.episodes)
    say = (lambda line: print(line, file=sys.stderr)) if args.json else print
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
