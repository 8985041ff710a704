"""The tuning commands: ``tune`` (an Optuna study of PPO's hyperparameters on a shared storage)
and ``train-seeds`` (one training per seed in parallel worker processes, then aggregated)."""
from __future__ import annotations

import argparse

from microconveyor_env.cli.base import command, count, emit, plot_path
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, env_kwarg, env_kwargs_of, minutes
from .evaluate import iqm_lines
from .rl import seed_arg


def _budget_args(p: argparse.ArgumentParser, steps_help: str) -> None:
    p.add_argument("--workers", type=count(1), default=1,
                   help="local worker processes (each trains on one core)")
    p.add_argument("--conf-file", default=None,
                   help="rl-zoo3 style YAML giving the base hyperparameters (default: the "
                        "shipped configs/ppo.yml)")
    p.add_argument("--eval-freq", type=count(0), default=250_000,
                   help="steps between periodic evaluations (0: none)")
    p.add_argument("--eval-targets", type=count(1), default=100, help="targets per evaluation")
    add_env_args(p, default=DEFAULT_ENV_ID,
                 what=" to train on (its entry in the conf file gives the base hyperparameters)")
    p.add_argument("--steps", type=count(1), default=None, help=steps_help)


def _tune_args(p: argparse.ArgumentParser) -> None:
    from ..rl.tuning.settings import DEFAULT_STUDY
    from ..rl.tuning.space import SPACE

    p.add_argument("--trials", type=count(1), default=20,
                   help="trials this command runs, split over its workers (other machines add "
                        "theirs to the same study)")
    p.add_argument("--out", default="runs/tune",
                   help="folder of the trials' run folders (OUT/STUDY/trial-N), the default "
                        "SQLite storage and best.yml (default: runs/tune)")
    p.add_argument("--storage", default=None,
                   help="Optuna storage URL shared by all workers: sqlite:///PATH (one machine) "
                        "or a database for many machines, e.g. postgresql://USER@HOST/DB "
                        "(default: $MICROCONVEYOR_TUNE_STORAGE, else sqlite:///OUT/optuna.db)")
    p.add_argument("--study", default=DEFAULT_STUDY, help=f"study name (default: {DEFAULT_STUDY})")
    p.add_argument("--trial-minutes", type=minutes, default=None,
                   help="wall budget of one trial [min] (default: none, --steps only)")
    p.add_argument("--seed", type=seed_arg, default=0,
                   help="training seed of every trial")
    p.add_argument("--sampler-seed", type=seed_arg, default=None,
                   help="seed of the TPE sampler (worker i uses SEED + i; default: random)")
    p.add_argument("--fix", type=env_kwarg, nargs="+", default=None, metavar="KEY:VALUE",
                   help=f"do not tune KEY, use VALUE; keys: {', '.join(SPACE)}")
    p.add_argument("--no-prune", action="store_true",
                   help="no median pruning on the periodic evaluations")
    p.add_argument("--best", default=None,
                   help="where to write the best trial's config entry (rl-zoo3 YAML; default: "
                        "OUT/STUDY/best.yml)")
    p.add_argument("--heartbeat", type=count(1), default=None, metavar="SECONDS",
                   help="a new study's heartbeat interval: a running trial without a heartbeat "
                        "for 3x this (its worker or machine lost) is marked failed (default: "
                        "60; a study keeps the one it was created with)")
    p.add_argument("--quiet", action="store_true", help="no line per finished trial on stderr")
    _budget_args(p, "environment steps per trial (default: 1,000,000)")


@command("tune", "search PPO hyperparameters with Optuna: workers (here and on other machines) "
                 "share one study in a database; writes the best as an rl-zoo3 config entry",
         _tune_args)
def cmd_tune(args: argparse.Namespace) -> None:
    from ..rl.tuning.settings import TuneSettings
    from ..rl.tuning.storage import default_storage, masked, secrets_masked
    from ..rl.tuning.tune import tune

    url = args.storage or default_storage(args.out)
    with secrets_masked(url):   # in errors and the result, the storage's secrets never shown
        res = masked(tune(TuneSettings(
            out=args.out, n_trials=args.trials, workers=args.workers, storage=args.storage,
            study_name=args.study, env_id=args.env, env_kwargs=env_kwargs_of(args) or None,
            conf_file=args.conf_file, trial_steps=args.steps or 1_000_000,
            trial_minutes=args.trial_minutes, eval_freq=args.eval_freq,
            eval_targets=args.eval_targets, seed=args.seed, fixed=dict(args.fix or []),
            prune=not args.no_prune, sampler_seed=args.sampler_seed, best_file=args.best,
            verbose=not args.quiet, heartbeat_s=args.heartbeat)), url)
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
    from ..rl.training.algos import ALGO_NAMES

    p.add_argument("--seeds", type=seed_arg, nargs="+", required=True,
                   help="training seeds")
    p.add_argument("--out", default="runs/seeds",
                   help="folder of the runs, one OUT/seed-S per seed (default: runs/seeds)")
    p.add_argument("--algo", choices=ALGO_NAMES, default="ppo", help="algorithm (default: ppo)")
    p.add_argument("--max-minutes", type=minutes, default=None,
                   help="wall budget of each run [min]")
    p.add_argument("--checkpoint-freq", type=count(1), default=200_000,
                   help="steps between checkpoints")
    p.add_argument("--resume", action="store_true",
                   help="continue each seed's newest checkpoint, if it has one (finished seeds "
                        "are always reused as they are)")
    p.add_argument("--plot", type=plot_path, default=None, help="write the learning curves here")
    p.add_argument("--quiet", action="store_true", help="no checkpoint and evaluation lines")
    _budget_args(p, "total environment steps per run (default: n_timesteps of the conf file)")


@command("train-seeds", "train one run per seed in parallel worker processes, then aggregate "
                        "them (IQM and bootstrap CI, as `seeds`)", _seeds_args)
def cmd_train_seeds(args: argparse.Namespace) -> None:
    from ..rl.training.parallel import train_seeds
    from ..rl.training.settings import TrainSettings

    settings = TrainSettings(algo=args.algo, steps=args.steps, conf_file=args.conf_file,
                             env_id=args.env, env_kwargs=env_kwargs_of(args) or None,
                             max_minutes=args.max_minutes, checkpoint_freq=args.checkpoint_freq,
                             eval_freq=args.eval_freq, eval_targets=args.eval_targets,
                             resume=args.resume)
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
