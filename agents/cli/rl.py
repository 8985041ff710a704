"""The RL commands that write policies: ``train``, ``refine`` and ``convert-stats`` (evaluating
them: :mod:`.evaluate`)."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from microconveyor_env.cli.base import command, count, emit, settings_from, settings_options
from microconveyor_env.env_ids import DEFAULT_ENV_ID, ENV_IDS

from .args import add_env_args, env_kwargs_of, minutes

SEED_MAX = 2**31 - 1   # the largest training seed (numpy, torch and every env seed take it)


def seed_arg(text: str) -> int:
    """A training seed option: a whole number in [0, :data:`SEED_MAX`]."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= v <= SEED_MAX:
        raise argparse.ArgumentTypeError(f"a seed is a whole number in [0, {SEED_MAX}], got {v}")
    return v

def _train_args(p: argparse.ArgumentParser) -> None:
    from ..rl.training.settings import TrainSettings

    parse = {"seed": seed_arg, "fork_seed": seed_arg, "max_minutes": minutes}
    settings_options(p, TrainSettings, ["algo"])
    p.add_argument("--out", default=None,
                   help="run folder (model, stats, checkpoints, logs) (default: runs/ALGO)")
    settings_options(p, TrainSettings, ["steps", "seed", "conf_file", "resume",
                                        "allow_config_change", "fork_seed", "checkpoint_freq",
                                        "eval_freq", "eval_targets", "max_minutes",
                                        "progress_bar"], parse=parse)
    p.add_argument("--quick", action="store_true",
                   help="a short look: PPO on v1's nearest targets (0.5-1.4 mm) with "
                        "configs/ppo_quick.yml unless --conf-file is given, --max-minutes 3 "
                        "(unless given), an evaluation on 50 targets every 250,000 steps printed "
                        "as it goes (docs/agents.md, 'The quick look')")
    p.add_argument("--refine", action="store_true",
                   help="then refine the final PPO policy (`microconveyor refine` at its "
                        "defaults, ~3 min) into OUT/refined, evaluated on --eval-targets; "
                        "MicroConveyor-v0/v1 without randomisation")
    add_env_args(p, default=DEFAULT_ENV_ID,
                 what=" to train on (its entry in the conf file gives the hyperparameters)")


def _check_refinable(args: argparse.Namespace) -> None:
    """Refuse ``train --refine`` before training where refine would refuse after it (its
    folder: checked and held by :func:`cmd_train`)."""
    from microconveyor_env.envs import env_config

    if args.algo != "ppo" or args.env not in ENV_IDS:
        raise ValueError(f"--refine refines a PPO policy of {' or '.join(ENV_IDS)}; got "
                         f"--algo {args.algo} --env {args.env}")
    if env_config(args.env, **env_kwargs_of(args)).randomised:
        raise ValueError("--refine corrects deterministic episodes; --env-kwargs asks for "
                         "per-episode randomisation")


def _refine_folder(policy: str, out: Any, settings: Any, eval_targets: int) -> dict[str, Any]:
    """Refine the policy folder ``policy`` into ``out`` (one torch thread), evaluate it on
    ``eval_targets`` targets of the policy's own evaluation seed (0: none); the command's
    result: the folder, the refinement report and the evaluations after and before."""
    import torch

    from ..rl.evaluation.evaluate import evaluate, load_policy
    from ..rl.refinement.refine import refine
    from ..rl.refinement.writer import write_refined

    pol = load_policy(policy)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)   # as in training: one core, the same arithmetic on every run
    try:
        report = refine(pol, settings, log=lambda line: print(line, file=sys.stderr, flush=True))
    finally:
        torch.set_num_threads(threads)
    before = pol.metadata.get("evaluation") or {}
    ev = evaluate(pol, eval_targets, int(before.get("seed", 12345))) if eval_targets else None
    written = write_refined(pol, report, out, ev)
    return {"out": str(written), "refinement": report, "evaluation": ev,
            "evaluation_before": before}


def _success_line(ev: dict[str, Any]) -> str:
    return (f"success within ±50/100/250 µm: {100 * ev['success_rate_50um']:.1f} / "
            f"{100 * ev['success_rate_100um']:.1f} / {100 * ev['success_rate_250um']:.1f} %, "
            f"median |error| {ev['median_abs_error_m'] * 1e6:.1f} µm")


def _kwargs_text(kwargs: dict[str, Any] | None) -> str:
    """Env kwargs as ``key=value, ...`` (values as given)."""
    return ", ".join(f"{k}={v}" for k, v in (kwargs or {}).items())


@command("train", "train PPO, SAC or TQC on any registered env (checkpoints, evaluations, "
                  "resume)",
         _train_args)
def cmd_train(args: argparse.Namespace) -> None:
    import contextlib
    from pathlib import Path

    from ..rl.artefacts.folders import NewPolicyFolder

    if args.refine:
        _check_refinable(args)
    with contextlib.ExitStack() as stack:
        # --refine's folder: checked and held from before the training to the end, so that a
        # second writer of it is refused before the training, not after the refinement
        refined = (stack.enter_context(NewPolicyFolder(
            Path(args.out or f"runs/{args.algo}") / "refined", "--refine's folder"))
            if args.refine else None)
        meta, text = _train(args, refined)
    emit(args, meta, text)


def _train(args: argparse.Namespace, refined: Any) -> tuple[dict[str, Any], str]:
    """``train`` (and with ``refined``, the held folder of ``--refine``, the refinement into
    it): the command's result and its text."""
    from ..rl.training.settings import TrainSettings
    from ..rl.training.train import train

    def log(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    if args.quick:
        args.max_minutes = args.max_minutes or 3.0
        args.eval_freq, args.eval_targets = 250_000, 50
        if args.conf_file is None and args.algo == "ppo" and args.env == "MicroConveyor-v1":
            from importlib import resources
            args.conf_file = str(resources.files("microconveyor_env.configs") / "ppo_quick.yml")
    args.out = args.out or f"runs/{args.algo}"
    settings = settings_from(TrainSettings, args, env_id=args.env,
                             env_kwargs=env_kwargs_of(args))
    meta = train(args.out, settings, log=log)
    meta["out"] = args.out
    ev = meta["evaluation"]
    kwargs = _kwargs_text(meta.get("env_kwargs"))
    text = (f"{meta['env_id']}{f' ({kwargs})' if kwargs else ''}: {meta['steps']} steps in "
            f"{meta['wall_time_s']:.0f} s -> {args.out}")
    if ev:
        text += "\n" + _success_line(ev)
    if refined is not None:
        from ..rl.refinement.settings import RefineSettings

        res = _refine_folder(args.out, refined, RefineSettings(), args.eval_targets)
        meta["refined"] = res
        text += (f"\nrefined -> {res['out']} ({res['refinement']['wall_time_s']:.0f} s, kept "
                 f"round {res['refinement']['kept_round']})")
        if res["evaluation"]:
            text += "\n" + _success_line(res["evaluation"])
    return meta, text


def _refine_args(p: argparse.ArgumentParser) -> None:
    from ..rl.refinement.settings import RefineSettings

    p.add_argument("policy", help="a trained PPO policy folder of the 1-D conveyor (model.zip, "
                                  "normalization.json, metadata.json; e.g. a `train` run folder)")
    p.add_argument("--out", required=True, help="the refined policy folder to write (must not "
                                                "exist or be empty)")
    settings_options(p, RefineSettings, ["targets", "rounds", "fit_iterations", "seed"])
    p.add_argument("--eval-targets", type=count(0), default=100,
                   help="targets of the evaluation written to the metadata, drawn with the "
                        "policy's own evaluation seed (0: none; default 100)")


@command("refine", "refine a trained policy's aim: Newton corrections of its last firing (and, "
                   "for near targets it overshoots, of its first firing alone) on the simulator, "
                   "fitted back into the actor (docs/agents.md, 'Refining the aim')",
         _refine_args)
def cmd_refine(args: argparse.Namespace) -> None:
    from pathlib import Path

    from ..rl.artefacts.folders import NewPolicyFolder
    from ..rl.refinement.settings import RefineSettings

    out = Path(args.out)
    settings = settings_from(RefineSettings, args)
    # checked and held before the refinement's minutes, not after them
    with NewPolicyFolder(args.out) as folder:
        res = _refine_folder(args.policy, folder, settings, args.eval_targets)
    report, ev = res["refinement"], res["evaluation"]
    text = f"refined policy -> {out} ({report['wall_time_s']:.0f} s, kept round {report['kept_round']})"
    if ev:
        text += f"\n{_success_line(ev)} on {ev['n_targets']} targets"
    emit(args, res, text)


def _convert_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("pickle", help="an SB3 vecnormalize.pkl you trust")
    p.add_argument("--out", default=None,
                   help="where to write the JSON (default: normalization.json beside it)")


@command("convert-stats", "convert a trusted SB3 vecnormalize.pkl to normalization.json (this "
                          "unpickles the file, which can run code: only for files you trust)",
         _convert_args)
def cmd_convert_stats(args: argparse.Namespace) -> None:
    from pathlib import Path

    from ..rl.artefacts.normalization import NORMALIZATION, convert_pickle

    src = Path(args.pickle)
    if not src.is_file():
        raise ValueError(f"no file {args.pickle!r}")
    out = Path(args.out) if args.out else src.parent / NORMALIZATION
    stats = convert_pickle(src, out)
    emit(args, {"normalization_json": str(out), "obs_dim": len(stats["obs_rms"]["mean"])},
         f"wrote {out} (observation statistics of dimension {len(stats['obs_rms']['mean'])})")
