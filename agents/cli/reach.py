"""The ``microconveyor reach`` command."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from microconveyor_env.cli.base import command, count, emit, plot_path

from .args import add_env_args, env_config_of, env_kwargs_of, floats, line_env


def _reach_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--targets", type=floats, default=floats("0.5e-3:12e-3:0.5e-3"),
                   help="targets [m]: lo:hi:step or a comma list (default 0.5-12 mm by 0.5 mm)")
    p.add_argument("--budget", type=count(10), default=3000,
                   help="DE episodes per target for the best nominal error")
    p.add_argument("--robust-budget", type=count(0), default=100000,
                   help="episodes per target for the noise-robust DE (0: skip)")
    p.add_argument("--sigma", type=float, default=1e-3, help="action noise (in [-1, 1] units)")
    p.add_argument("--noisy", type=count(1), default=200, help="noisy rollouts per answer")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", type=plot_path, default=None, help="write the reach chart here")
    add_env_args(p,
                 what=" whose scene is studied (its target_range is ignored: --targets)")


@command("reach", "open-loop reach study: best DE error per target and its success under "
                  "action noise; the widest robust target range", _reach_args)
def cmd_reach(args: argparse.Namespace) -> None:
    from ..experiments.reach import reach_study
    from ..plots.reach import plot_reach

    def progress(r: dict[str, Any]) -> None:
        print(f"target {r['target_m'] * 1e3:6.2f} mm  best |err| {r['best_abs_error_m'] * 1e6:10.2f}"
              f" µm  noisy success {100 * r['noisy_success_rate']:.1f} % / best "
              f"{100 * r['best_noisy_success_rate']:.1f} %  ({r['wall_time_s']:.1f} s)",
              file=sys.stderr,
              flush=True)

    line_env(args.env, "reach")
    kwargs = env_kwargs_of(args)
    if max(args.targets) > 0.1 or min(args.targets) <= 0:
        raise ValueError("--targets must lie in (0, 0.1] m")
    cfg = env_config_of(args, target_range=(min(args.targets), max(args.targets)))
    study = reach_study(args.targets, budget=args.budget, sigma=args.sigma, n_noisy=args.noisy,
                        seed=args.seed, robust_budget=args.robust_budget, config=cfg,
                        progress=progress)
    study.update(env_id=args.env, env_kwargs=kwargs,
                 scene_label=f"{args.env}: {cfg.n_actuators} actuators {cfg.spacing * 1e3:g} mm "
                             f"apart, preset {cfg.preset}, action noise σ = {args.sigma:g}")
    if args.plot:
        study["plot"] = plot_reach(study, args.plot)  # after the scene label is in
    emit(args, study, reach_text(study))


def reach_text(study: dict[str, Any]) -> str:
    """The reach study in the units people read: per target the best nominal error, the success
    under action noise of the better plan, and the widest robust target range."""
    lines = [study["scene_label"],
             f"{'target':>9}  {'best |error|':>12}  {'noisy success':>13}",
             *(f"{r['target_m'] * 1e3:6.2f} mm  {r['best_abs_error_m'] * 1e6:9.2f} µm  "
               f"{100 * r['best_noisy_success_rate']:11.1f} %  {'robust' if r['robust'] else ''}"
               .rstrip() for r in study["rows"])]
    rng = study["robust_target_range_m"]
    lines.append("robust target range (noisy success >= "
                 f"{100 * study['robust_rate']:.0f} % within {study['tolerance_m'] * 1e6:.0f} µm): "
                 + (f"{rng[0] * 1e3:.2f} to {rng[1] * 1e3:.2f} mm" if rng else "none"))
    return "\n".join(lines)


