"""The ``microconveyor optimize`` command."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from microconveyor_env.cli.base import command, companion, count, emit, plot_path
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from ..openloop.search import TARGET_BUDGET
from .args import add_env_args, env_config_of, env_kwargs_of, line_env

PROBLEMS = ("target", "dissertation")


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--problem", choices=PROBLEMS, default="target",
                   help="target: the env's 15 per-firing actions for one target; dissertation: "
                        "4 shared numbers (frequency, spacing, delay, stroke), 10 mm target")
    p.add_argument("--method", choices=("de", "cmaes"), default="de")
    p.add_argument("--target", type=float, default=None,
                   help="target [m] beyond actuator 1 (default: 2e-3 for target, 10e-3 for "
                        "dissertation)")
    p.add_argument("--budget", type=count(10, 10_000_000), default=None,
                   help=f"episodes (used <= budget; default {TARGET_BUDGET} for target, 2550 = "
                        "50 x (50 + 1) for dissertation). DE on MicroConveyor-v1: 2000 reaches "
                        "targets to 6 mm, 10000 to 8 mm, and 9-10 mm for 2 seeds of 3 (~10 s)")
    p.add_argument("--popsize", type=count(2, 100_000), default=None,
                   help="population per generation (default: 15 for DE on target, 50 for DE on "
                        "dissertation, pycma's for CMA-ES)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", type=plot_path, default=None,
                   help="chart file (the best plan's trajectory); the search's history goes "
                        "beside it as STEM_history")
    p.add_argument("--explain", action="store_true",
                   help="dissertation: also replay Table 4.3's schedule under one-at-a-time model "
                        "changes and re-run the DE under each, for 10 seeds from --seed (~30 s "
                        "at the default budget)")
    add_env_args(p, default=None, default_text=DEFAULT_ENV_ID,
                 what=" of --problem target (the dissertation problem is its own model)")


def run(args: argparse.Namespace) -> None:
    if args.target is not None and not 0 < args.target <= 0.1:
        raise ValueError(f"--target {args.target!r} must be in (0, 0.1] m")
    if args.popsize is not None and args.method == "de" and args.popsize < 5:
        raise ValueError("--popsize: DE needs at least 5 members")
    if args.popsize is not None and args.budget is not None and args.popsize > args.budget:
        raise ValueError(f"--popsize {args.popsize} is larger than --budget {args.budget}")
    if args.plot:
        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
    if args.problem == "dissertation":
        if args.env or args.env_kwargs:
            raise ValueError("--env/--env-kwargs/--preset belong to --problem target; the "
                             "dissertation problem is its own model (5 actuators, chapter 4's "
                             "surface)")
        out, text = _dissertation(args)
    else:
        if args.explain:
            raise ValueError("--explain belongs to --problem dissertation")
        out, text = _target(args)
    emit(args, out, text)


def _target(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..openloop.target import plan_trajectory, solve_target
    from ..plots.optimize import plot_error_history
    from ..plots.trajectories import plot_plan_trajectories

    target = 2e-3 if args.target is None else args.target
    kw = {} if args.popsize is None else {"popsize": args.popsize}
    env_id, env_kw = line_env(args.env or DEFAULT_ENV_ID, "optimize"), env_kwargs_of(args)
    cfg = env_config_of(args)
    res = solve_target(target, args.method, args.budget or TARGET_BUDGET, args.seed, config=cfg,
                       **kw)
    out: dict[str, Any] = {"problem": "target", "env_id": env_id, "env_kwargs": env_kw,
                           **res.to_dict()}
    if args.plot:
        out["plots"] = [
            plot_error_history(res.history_episodes, res.history_best_abs_error_m,
                               res.tolerance_m, companion(args.plot, "history"),
                               f"{args.method}: target {target * 1e3:g} mm, seed {args.seed}"),
            plot_plan_trajectories({f"{args.method} best plan": plan_trajectory(res.plan, target,
                                                                                cfg)},
                              args.plot, target,
                              title=f"Best open-loop plan for {target * 1e3:g} mm")]
    text = (f"target {target * 1e3:g} mm, {args.method}, {res.episodes} episodes in "
            f"{res.wall_time_s:.2f} s: rests at {res.final_position_m * 1e3:.4f} mm "
            f"(|error| {res.abs_error_m * 1e6:.2f} µm, {res.outcome}, success {res.success})")
    return out, text


def _dissertation(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..openloop.dissertation import TABLE_4_3, DissertationProblem, evaluate_parameters, \
        solve_dissertation, trajectory
    from ..plots.optimize import plot_cost_history
    from ..plots.trajectories import plot_plan_trajectories

    prob = DissertationProblem() if args.target is None else DissertationProblem(args.target)
    res = solve_dissertation(args.method, args.seed, args.budget, prob, args.popsize)
    ours = evaluate_parameters(TABLE_4_3, prob)
    out: dict[str, Any] = {
        "problem": "dissertation", **res.to_dict(),
        "cost_settings": {"target_m": prob.target_m, "x0_m": prob.x0_m,
                          "time_weight_A_per_s": prob.time_weight, "scale_T_d_m": prob.scale_m,
                          "exponent_C": prob.exponent, "detach_penalty_P": prob.penalty},
        "table_4_3": {"dissertation": TABLE_4_3, "this_model": ours}}
    if args.plot:
        label = (f"optimum ({res.parameters['frequency_hz']:.0f} Hz, "
                 f"{res.parameters['spacing_m'] * 1e6:.0f} µm, "
                 f"{res.parameters['delay_s'] * 1e3:.2f} ms, "
                 f"{res.parameters['stroke_m'] * 1e6:.0f} µm)")
        out["plots"] = [
            plot_cost_history({args.method: (res.history_episodes, res.history_best_cost)},
                              companion(args.plot, "history")),
            plot_plan_trajectories({label: trajectory(res.parameters, prob),
                               "Table 4.3 (719 Hz, 500 µm, 1 ms, 178 µm)":
                               trajectory(TABLE_4_3, prob)},
                              args.plot, prob.target_m)]
    if args.explain:
        from ..openloop.table43 import explain

        def progress(row: dict[str, Any]) -> None:
            print(f"{row['variant'][:58]:58s} Table 4.3 -> "
                  f"{row['table43_final_position_m'] * 1e3:7.3f} mm; DE median "
                  f"{row['de_median_final_position_m'] * 1e3:7.3f} mm in "
                  f"{row['de_median_travel_time_s'] * 1e3:6.1f} ms, {row['de_goal_hits']}/"
                  f"{len(row['de_seeds'])} seeds within 50 µm in <= 50 ms", file=sys.stderr,
                  flush=True)

        out["explain"] = explain(prob, seeds=range(args.seed, args.seed + 10),
                                 budget=args.budget, progress=progress)
    p = res.parameters
    text = (f"{args.method} optimum: {p['frequency_hz']:.1f} Hz, spacing "
            f"{p['spacing_m'] * 1e6:.1f} µm, delay {p['delay_s'] * 1e3:.3f} ms, stroke "
            f"{p['stroke_m'] * 1e6:.1f} µm -> {res.final_position_m * 1e3:.3f} mm "
            f"({res.outcome}) in {res.travel_time_s:.4f} s, cost {res.cost:.4g}; "
            f"{res.episodes} episodes in {res.wall_time_s:.2f} s\n"
            f"Table 4.3 (719 Hz, 500 µm, 1 ms, 178 µm): dissertation 10.02 mm in 0.037 s; "
            f"this model {ours['final_position_m'] * 1e3:.3f} mm ({ours['outcome']}) in "
            f"{ours['travel_time_s']:.4f} s")
    return out, text


def _optimize_args(p: argparse.ArgumentParser) -> None:
    add_args(p)


@command("optimize", "open-loop optimisation: the env's per-firing plan for one target, or the "
                     "dissertation's shared-parameter problem (DE or CMA-ES, batched, seeded)",
         _optimize_args)
def cmd_optimize(args: argparse.Namespace) -> None:
    run(args)
