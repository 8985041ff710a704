"""The agents' ``microconveyor`` commands: ``reach``, ``optimize``, ``compare``, ``train``,
``evaluate``, ``seeds`` and ``demo`` (the last replaces the env package's demo with one that runs the shipped policy).

Loaded through the ``microconveyor_env.commands`` entry point (pyproject.toml): importing this
module registers the commands with :func:`microconveyor_env.cli.base.command`.
"""
from __future__ import annotations

import sys

from microconveyor_env.cli.base import command, count, emit, plot_path


def _floats(text: str) -> list:
    import argparse

    try:
        if ":" in text:
            lo, hi, step = (float(v) for v in text.split(":"))
            import numpy as np
            return [float(v) for v in np.arange(lo, hi + step / 2, step)]
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give lo:hi:step or a comma list") from None


def _reach_args(p):
    p.add_argument("--targets", type=_floats, default=_floats("0.5e-3:10e-3:0.5e-3"),
                   help="targets [m]: lo:hi:step or a comma list (default 0.5-10 mm by 0.5 mm)")
    p.add_argument("--budget", type=count(10), default=3000,
                   help="DE episodes per target for the best nominal error")
    p.add_argument("--robust-budget", type=count(0), default=100000,
                   help="episodes per target for the noise-robust DE (0: skip)")
    p.add_argument("--sigma", type=float, default=1e-3, help="action noise (in [-1, 1] units)")
    p.add_argument("--noisy", type=count(1), default=200, help="noisy rollouts per answer")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", type=plot_path, default=None, help="write the reach chart here")


@command("reach", "open-loop reach study: best DE error per target and its success under "
                  "action noise; the widest robust target range", _reach_args)
def cmd_reach(args):
    from .reach import plot_reach, reach_study

    def progress(r):
        print(f"target {r['target_m'] * 1e3:6.2f} mm  best |err| {r['best_abs_error_m'] * 1e6:10.2f}"
              f" um  noisy success {r['noisy_success_rate']:.2f} / best "
              f"{r['best_noisy_success_rate']:.2f}  ({r['wall_time_s']:.1f} s)", file=sys.stderr,
              flush=True)

    study = reach_study(args.targets, budget=args.budget, sigma=args.sigma, n_noisy=args.noisy,
                        seed=args.seed, robust_budget=args.robust_budget, progress=progress)
    if args.plot:
        study["plot"] = plot_reach(study, args.plot)
    rows = "\n".join(f"{r['target_m'] * 1e3:6.2f} mm  {r['best_abs_error_m'] * 1e6:10.2f} um  "
                     f"{r['best_noisy_success_rate']:.2f}  {'robust' if r['robust'] else ''}"
                     for r in study["rows"])
    emit(args, study, rows + f"\nrobust target range: {study['robust_target_range_m']}")


def _optimize_args(p):
    from .cli_optimize import add_args

    add_args(p)


@command("optimize", "open-loop optimisation: the env's per-firing plan for one target, or the "
                     "dissertation's shared-parameter problem (DE or CMA-ES, batched, seeded)",
         _optimize_args)
def cmd_optimize(args):
    from .cli_optimize import run

    run(args)


def _compare_args(p):
    from .cli_compare import add_args

    add_args(p)


@command("compare", "closed loop vs open loop on fixed targets: PPO (shipped and trained with "
                    "randomisation), DE and CMA-ES at several budgets, a random policy and a fixed "
                    "schedule; accuracy vs compute, success vs tolerance and vs perturbation",
         _compare_args)
def cmd_compare(args):
    from .cli_compare import run

    run(args)


def _minutes(text: str) -> float:
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of minutes") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number of minutes, got {text}")
    return v


def _train_args(p):
    p.add_argument("--out", default="runs/ppo", help="run folder (model, stats, checkpoints, logs)")
    p.add_argument("--steps", type=count(1), default=None,
                   help="total environment steps (default: n_timesteps of the conf file)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--conf-file", default=None, help="rl-zoo3 style YAML (default configs/ppo.yml)")
    p.add_argument("--resume", action="store_true",
                   help="continue from the newest complete checkpoint in OUT/checkpoints "
                        "(refused if there is none or the config differs)")
    p.add_argument("--allow-config-change", action="store_true",
                   help="with --resume: continue under a different config (recorded in the "
                        "metadata)")
    p.add_argument("--checkpoint-freq", type=count(1), default=200_000,
                   help="steps between checkpoints (a kill loses at most this many)")
    p.add_argument("--eval-freq", type=count(0), default=250_000, help="0: no periodic evaluation")
    p.add_argument("--eval-targets", type=count(0), default=100,
                   help="targets per evaluation (0: no evaluation)")
    p.add_argument("--max-minutes", type=_minutes, default=None,
                   help="stop after this wall time [min], resumed time included")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


@command("train", "train PPO (stable-baselines3) on the batched env", _train_args)
def cmd_train(args):
    from .train import train

    def log(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    meta = train(args.out, steps=args.steps, seed=args.seed, conf_file=args.conf_file,
                 resume=args.resume, checkpoint_freq=args.checkpoint_freq,
                 eval_freq=args.eval_freq, eval_targets=args.eval_targets,
                 progress_bar=not args.no_progress, max_minutes=args.max_minutes,
                 allow_config_change=args.allow_config_change, log=log)
    meta["out"] = args.out
    ev = meta["evaluation"]
    text = f"{meta['steps']} steps in {meta['wall_time_s']:.0f} s -> {args.out}"
    if ev:
        text += (f"\nsuccess +-50/100/250 um: {ev['success_rate_50um']:.2f} / "
                 f"{ev['success_rate_100um']:.2f} / {ev['success_rate_250um']:.2f}, median "
                 f"|error| {ev['median_abs_error_m'] * 1e6:.1f} um")
    emit(args, meta, text)


def _convert_args(p):
    p.add_argument("pickle", help="an SB3 vecnormalize.pkl you trust")
    p.add_argument("--out", default=None,
                   help="where to write the JSON (default: normalization.json beside it)")


@command("convert-stats", "convert a trusted SB3 vecnormalize.pkl to normalization.json (this "
                          "unpickles the file, which can run code: only for files you trust)",
         _convert_args)
def cmd_convert_stats(args):
    from pathlib import Path

    from .normalization import NORMALIZATION, convert_pickle

    src = Path(args.pickle)
    if not src.is_file():
        raise ValueError(f"no file {args.pickle!r}")
    out = Path(args.out) if args.out else src.parent / NORMALIZATION
    stats = convert_pickle(src, out)
    emit(args, {"normalization_json": str(out), "obs_dim": len(stats["obs_rms"]["mean"])},
         f"wrote {out} (observation statistics of dimension {len(stats['obs_rms']['mean'])})")


def _evaluate_args(p):
    p.add_argument("--policy", default=None, help="policy folder or model zip (default: shipped)")
    p.add_argument("--targets", type=count(1, 100000), default=100, help="number of targets")
    p.add_argument("--seed", type=int, default=0, help="seed of the fixed target set")
    p.add_argument("--tolerance", type=float, default=None,
                   help="success tolerance [m] (default: the env's, 50 um)")


@command("evaluate", "evaluate a PPO policy on a fixed seeded set of targets", _evaluate_args)
def cmd_evaluate(args):
    from .evaluate import evaluate, load_policy
    from .policy import shipped_path

    if args.tolerance is not None and not 0 < args.tolerance < 1:
        raise ValueError(f"--tolerance {args.tolerance!r} must be in (0, 1) m")
    pol = load_policy(args.policy or shipped_path())
    res = evaluate(pol, args.targets, args.seed, args.tolerance)
    res["policy"] = str(pol.path)
    emit(args, res)


def _seeds_args(p):
    p.add_argument("runs", nargs="+", help="run folders of `microconveyor train`")
    p.add_argument("--plot", type=plot_path, default=None, help="write the learning curves here")


@command("seeds", "aggregate training runs over seeds: IQM and bootstrap CI of the final "
                  "evaluations, learning curves", _seeds_args)
def cmd_seeds(args):
    from .seeds import aggregate, curves, plot_curves

    res = aggregate(args.runs)
    res["curves"] = curves(args.runs)
    if args.plot:
        res["plot"] = plot_curves(res["curves"], args.plot)
    lines = [f"{k}: IQM {v['iqm']:.4g}, 95 % CI [{v['ci95'][0]:.4g}, {v['ci95'][1]:.4g}], per "
             f"seed {', '.join(f'{x:.4g}' for x in v['per_seed'])}"
             for k, v in res.items() if isinstance(v, dict) and "iqm" in v]
    emit(args, res, "\n".join(lines))


def _demo_args(p):
    p.add_argument("--out", default="out", help="output folder for charts and the summary JSON")
    p.add_argument("--policy", default=None, help="policy folder (default: the shipped one)")


@command("demo", "the main job: contact report, a firing, a frequency sweep, an env episode and "
                 "the shipped PPO policy on a few targets; charts written to --out", _demo_args)
def cmd_demo(args):
    import json
    from pathlib import Path

    from microconveyor_env.cli.base import json_default
    from microconveyor_env.cli.demo import demo_summary

    from .demo import load_demo_policy, policy_demo, table

    policy = load_demo_policy(args.policy)   # a bad --policy fails before any other work
    summary = demo_summary(args)
    demo = policy_demo(args.out, policy)
    summary["policy_demo"] = demo
    summary["charts"].append(demo["chart"])
    Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2, default=json_default))
    text = table(demo)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, summary, text + "\n" + "\n".join(f"wrote {c}" for c in summary["charts"] +
                                                [summary["summary_json"]]))
