"""The ``microconveyor place`` command: one part to one target with a policy, MPC or DE."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from microconveyor_env.cli.base import command, count, emit, field_default
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, env_kwargs_of, level, scene_config_of, target_point
from .compare import mpc_budgets


def _place_args(p: argparse.ArgumentParser) -> None:
    from ..experiments.place import DE_BUDGET, METHODS, POSITIONER_DE_BUDGET
    from ..mpc import MPCSettings
    from ..planning.cost import TIME_WEIGHT

    p.add_argument("--target", type=target_point, required=True, metavar="M|X,Y",
                   help="target [m]: on the line and the positioner the distance beyond "
                        "actuator 1 (e.g. 9e-3), within the env's target range; on the plane "
                        "X,Y within the actuator grid's box (e.g. 1.5e-3,0.5e-3)")
    p.add_argument("--method", choices=METHODS, default="policy",
                   help="policy: the env's default shipped policy (or --policy), closed loop; "
                        "mpc: model-based control on the nominal model (the line: "
                        "model-predictive control, its searches seeded by that policy's plan; "
                        "the positioner: its one-step controller, friction identified online; "
                        "the plane: its one-step controller on the firing map); "
                        "de: differential evolution's open-loop plan on the nominal model (the "
                        "line: a firing per actuator; the positioner: a few firings of any "
                        "actuator; not on the plane, MicroConveyor2D-v0, -v1) "
                        "(default: policy)")
    p.add_argument("--policy", default=None,
                   help="policy folder for --method policy, or the seed of the line's --method "
                        "mpc (default: the one shipped for --env by default)")
    p.add_argument("--seed", type=count(0, 2**31 - 1), default=0,
                   help="the episode's seed and the searches' (an integer >= 0)")
    p.add_argument("--budget", type=count(10, 10_000_000), default=None,
                   help=f"--method de: episodes of the search (default {DE_BUDGET} on the line, "
                        f"{POSITIONER_DE_BUDGET} on the positioner)")
    p.add_argument("--mpc-budgets", type=mpc_budgets, default=None, metavar="FIRST,REPLAN",
                   help="--method mpc on the line: episodes of the model before the first firing "
                        f"and per re-plan (default {field_default(MPCSettings, 'first_budget')},"
                        f"{field_default(MPCSettings, 'replan_budget')})")
    p.add_argument("--tolerance", type=float, default=None, metavar="M",
                   help="the precision asked for [m] (e.g. 1e-5 for ±10 µm; up to 1e-3): the "
                        "env's tolerance, within which the part must rest (the episode ends "
                        "once it does), for every method: a request-conditioned policy reads it, "
                        "MPC and DE stop there (default: the env's, 50 µm)")
    p.add_argument("--time-weight", type=float, default=None, metavar="A",
                   help="--method de: trade placement time for precision, minimising A × "
                        "placement time [s] + (error / tolerance)^10 (the dissertation's cost; "
                        "inside the tolerance the sooner rest wins, outside it the nearer); "
                        f"A in 1/s, 0 for precision only (default: {TIME_WEIGHT:g} on the "
                        "line with --tolerance, else 0: on the positioner, at its default "
                        "budget, the weight costs more precision than the time it saves)")
    p.add_argument("--noise", type=level, default=0.0, metavar="SIGMA",
                   help="execution noise σ [action units] of the placement (default 0)")
    p.add_argument("--spread", type=level, default=0.0, metavar="R",
                   help="model error: friction and mass factors drawn in [1-r, 1+r] for the "
                        "placement (default 0); the planners plan on the nominal model")
    add_env_args(p, what=" (the line's, the positioner or the plane)")


@command("place", "place one part at one target, within the precision asked for, with the "
                  "default shipped policy, model-based control or DE: the plan (each firing), "
                  "the rest position, the error, the placement time and the compute",
         _place_args)
def cmd_place(args: argparse.Namespace) -> None:
    from ..experiments.perturb import Level
    from ..experiments.place import de_budget, geometry_of, place, place_text
    from ..mpc import MPCSettings
    from ..planning.cost import TIME_WEIGHT

    env_id = args.env or DEFAULT_ENV_ID
    cfg = scene_config_of(args)
    geometry = geometry_of(cfg)
    if args.method != "de" and args.budget is not None:
        raise ValueError("--budget is DE's search: give it with --method de")
    if args.mpc_budgets is not None and (args.method != "mpc" or geometry != "line"):
        raise ValueError("--mpc-budgets is the line's MPC's: give it with --method mpc on a "
                         "line's env (the positioner's controller tries a fixed grid of firings)")
    if args.policy is not None and (args.method == "de" or (args.method == "mpc"
                                                            and geometry != "line")):
        raise ValueError("--policy acts (--method policy) or seeds the line's MPC (--method "
                         f"mpc); {args.method} on {env_id} uses none")
    if args.time_weight is not None and args.method != "de":
        raise ValueError(f"--time-weight is DE's cost: give it with --method de, not "
                         f"{args.method}")
    if args.time_weight is not None and not 0.0 <= args.time_weight < float("inf"):
        raise ValueError(f"--time-weight {args.time_weight:g} is invalid: must be a number >= 0 "
                         "[1/s] (0: precision only)")
    weight = args.time_weight
    if (weight is None and args.method == "de" and args.tolerance is not None
            and geometry == "line"):
        weight = TIME_WEIGHT
    if args.mpc_budgets == (0, 0):
        raise ValueError("--mpc-budgets 0: --method mpc needs budgets (FIRST,REPLAN)")
    real = Level(args.noise, args.spread).config(cfg) if args.noise or args.spread else cfg
    mpc = None
    if args.mpc_budgets is not None:
        mpc = MPCSettings(first_budget=args.mpc_budgets[0], replan_budget=args.mpc_budgets[1],
                          seed=args.seed)

    def placing() -> None:
        if not args.json:
            print(f"placing with {args.method} ...", file=sys.stderr, flush=True)

    res: dict[str, Any] = place(args.target, args.method, real, policy=args.policy, seed=args.seed,
                                budget=args.budget or de_budget(cfg), mpc=mpc, env_id=env_id,
                                checked=placing, tolerance=args.tolerance,
                                time_weight=weight or None)
    res.update(env_id=env_id, env_kwargs=env_kwargs_of(args), noise=args.noise,
               spread=args.spread)
    emit(args, res, place_text(res))
