"""The tuning commands: ``tune`` (an Optuna study of PPO's hyperparameters on a shared storage)
and ``train-seeds`` (one training per seed in parallel worker processes, then aggregated)."""
from __future__ import annotations

import argparse

from microconveyor_env.cli.base import (command, count, emit, plot_path, settings_from,
                                        settings_options)
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, env_kwarg, env_kwargs_of, minutes
from .evaluate import iqm_lines
from .rl import seed_arg


def _tune_args(p: argparse.ArgumentParser) -> None:
    from ..rl.tuning.settings import TuneSettings

    settings_options(p, TuneSettings, ["n_trials", "out", "storage", "study_name",
                                       "trial_minutes", "seed", "sampler_seed", "fixed", "prune",
                                       "best_file", "heartbeat_s"],
                     parse={"trial_minutes": minutes, "seed": seed_arg, "sampler_seed": seed_arg,
                            "fixed": env_kwarg})
    p.add_argument("--quiet", action="store_true", help="no line per finished trial on stderr")
    settings_options(p, TuneSettings, ["workers", "conf_file", "eval_freq", "eval_targets"])
    add_env_args(p, default=DEFAULT_ENV_ID,
                 what=" to train on (its entry in the conf file gives the base hyperparameters)")
    settings_options(p, TuneSettings, ["trial_steps"])


@command("tune", "search PPO hyperparameters with Optuna: workers (here and on other machines) "
                 "share one study in a database; writes the best as an rl-zoo3 config entry",
         _tune_args)
def cmd_tune(args: argparse.Namespace) -> None:
    from ..rl.tuning.settings import TuneSettings
    from ..rl.tuning.storage import default_storage, masked, secrets_masked
    from ..rl.tuning.tune import tune

    url = args.storage or default_storage(args.out)
    with secrets_masked(url):   # in errors and the result, the storage's secrets never shown
        res = masked(tune(settings_from(
            TuneSettings, args, env_id=args.env, env_kwargs=env_kwargs_of(args) or None,
            fixed=dict(args.fixed or []), verbose=not args.quiet)), url)
    emit(args, res, tune_text(res))
    failed = res["failed"]
    if failed or res["died"]:
        first = failed[0] if failed else None
        raise ValueError(
            f"{len(failed)} of this run's {len(res['this_run'])} trials failed"
            + (f" (trial {first['number']}: {first['error']}"
               + (", ..." if len(failed) > 1 else "") + ")" if first else "")
            + "".join(f"; {d['not_run']} trial(s) of worker {d['worker']} not run"
                      for d in res["died"] if d["not_run"]))


def tune_text(res: dict) -> str:
    """The human summary of :func:`agents.rl.tuning.tune.tune`'s result."""
    states = ", ".join(f"{n} {s}" for s, n in sorted(res["states"].items()))
    mine: dict[str, int] = {}
    for r in res["this_run"]:
        mine[r["worker"]] = mine.get(r["worker"], 0) + 1
    lines = [f"study {res['study']!r} in {res['storage']}: {res['trials']} trials ({states}) "
             f"from {len(res['workers'])} worker(s)",
             f"this run: {len(res['this_run'])} trials in {res['wall_time_s']:.0f} s, per worker "
             + ", ".join(f"{w} {n}" for w, n in mine.items())]
    lines += [f"  failed: trial {f['number']} ({f['worker']}): {f['error']}" for f in res["failed"]]
    lines += [f"  worker {d['worker']} died ({d['how']})"
              + (f" in trial {d['trial']}" if d["trial"] is not None else "")
              + (f"; {d['not_run']} of its trials not run" if d["not_run"] else "")
              for d in res["died"]]
    b = res["best"]
    if b is None:
        lines.append("no finished trial yet: no best.yml")
    else:
        lines += [f"best: trial {b['number']}: {b['success_rate_50um']:.0%} within ±50 µm, "
                  f"median |error| {b['median_abs_error_m'] * 1e6:.1f} µm after "
                  f"{b['steps']:,} steps ({b['run']})",
                  "  hyperparameters: " + ", ".join(
                      f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                      for k, v in b["params"].items()),
                  f"config entry: {res['best_file']} (microconveyor train --env "
                  f"{res['env_id']} --conf-file {res['best_file']})"]
    return "\n".join(lines)


def _seeds_args(p: argparse.ArgumentParser) -> None:
    from ..rl.training.settings import TrainSettings

    p.add_argument("--seeds", type=seed_arg, nargs="+", required=True,
                   help="training seeds")
    p.add_argument("--out", default="runs/seeds",
                   help="folder of the runs, one OUT/seed-S per seed (default: runs/seeds)")
    settings_options(p, TrainSettings, ["algo", "max_minutes", "checkpoint_freq", "resume"],
                     parse={"max_minutes": minutes},
                     help_={"resume": "continue each seed's newest checkpoint, if it has one "
                                      "(finished seeds are always reused as they are)"})
    p.add_argument("--plot", type=plot_path, default=None, help="write the learning curves here")
    p.add_argument("--quiet", action="store_true", help="no checkpoint and evaluation lines")
    p.add_argument("--workers", type=count(1), default=1,
                   help="local worker processes (each trains on one core)")
    settings_options(p, TrainSettings, ["conf_file", "eval_freq", "eval_targets"],
                     parse={"eval_targets": count(1)},
                     help_={"eval_targets": "targets per evaluation"})
    add_env_args(p, default=DEFAULT_ENV_ID,
                 what=" to train on (its entry in the conf file gives the base hyperparameters)")
    settings_options(p, TrainSettings, ["steps"])


@command("train-seeds", "train one run per seed in parallel worker processes, then aggregate "
                        "them (IQM and bootstrap CI, as `seeds`)", _seeds_args)
def cmd_train_seeds(args: argparse.Namespace) -> None:
    from ..rl.training.parallel import train_seeds
    from ..rl.training.settings import TrainSettings

    settings = settings_from(TrainSettings, args, env_id=args.env,
                             env_kwargs=env_kwargs_of(args) or None)
    res = train_seeds(args.out, args.seeds, settings, workers=args.workers,
                      verbose=not args.quiet)
    lines = [f"seed {r['seed']}: {r['status']}" + (f" ({r['error']})" if "error" in r else
                                                  f", {r['steps']} steps, {r['wall_time_s']:.0f} s")
             for r in res["runs"]]
    agg = res["aggregate"]
    if agg is not None:
        if args.plot:
            from ..plots.seeds import plot_curves
            from ..rl.evaluation.seeds import curves

            res["plot"] = plot_curves(curves(agg["runs"]), args.plot)
        lines += iqm_lines(agg, per_seed=False)
    emit(args, res, "\n".join(lines))
    if any(r["status"] == "failed" for r in res["runs"]):
        raise ValueError(f"{sum(r['status'] == 'failed' for r in res['runs'])} seed(s) failed "
                         "(their errors above); the others are aggregated")
