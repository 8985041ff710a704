"""The RL commands that read policies and runs: ``evaluate`` (a policy on a fixed, seeded set of
targets, on any registered env) and ``seeds`` (training runs aggregated over seeds)."""
from __future__ import annotations

import argparse
from typing import Any

from microconveyor_env.cli.base import command, count, emit, plot_path

from .args import add_env_args, env_kwargs_of


def _evaluate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", default=None, help="policy folder or model zip (default: shipped)")
    p.add_argument("--targets", type=count(1, 100000), default=100, help="number of targets")
    p.add_argument("--seed", type=int, default=0, help="seed of the fixed target set")
    p.add_argument("--tolerance", type=float, default=None,
                   help="success tolerance [m] (default: the env's, 50 um)")
    add_env_args(p, default=None, default_text="the policy's own, from its metadata",
                 what=": refused if it differs from the scene the policy was trained in "
                      "(randomisation aside); needed for a policy without metadata.json; the "
                      "plane's targets lie on its grid's box and its errors are Euclidean")


@command("evaluate", "evaluate a policy (PPO, SAC, TQC, TD3) on a fixed seeded set of targets, "
                     "in the env it was trained on (its per-episode randomisation included)",
         _evaluate_args)
def cmd_evaluate(args: argparse.Namespace) -> None:
    """``env_kwargs`` in the result are the ones evaluated with (the policy's own updated by
    ``--env-kwargs``), ``trained_env_kwargs`` the policy's own."""
    from microconveyor_env.env_ids import DEFAULT_ENV_ID
    from microconveyor_env.envs.versions import scene_config

    from ..rl.artefacts.policy_files import policy_env_kwargs, read_policy_meta
    from ..rl.artefacts.shipped import require_shipped
    from ..rl.evaluation.evaluate import evaluate, load_policy

    if args.tolerance is not None and not 0 < args.tolerance < 1:
        raise ValueError(f"--tolerance {args.tolerance!r} must be in (0, 1) m")
    path = args.policy or require_shipped(args.env or DEFAULT_ENV_ID)
    meta = read_policy_meta(path)
    trained_kwargs = policy_env_kwargs(meta)
    kwargs = {**trained_kwargs, **env_kwargs_of(args)}
    asked = None
    if args.env or args.env_kwargs:
        # the env asked for: the policy's own kwargs updated by --env-kwargs, on --env (or
        # the policy's env id); load_policy refuses another scene, or a policy that names no
        # env id when --env does not either
        env_id = args.env or meta.get("env_id")
        asked = scene_config(env_id, **kwargs) if env_id else None
    pol = load_policy(path, asked, env_id=args.env)
    res = evaluate(pol, args.targets, args.seed, args.tolerance, config=asked)
    res.update(policy=str(pol.path), env_id=pol.env_id, env_kwargs=kwargs,
               trained_env_kwargs=trained_kwargs)
    emit(args, res)


def _seeds_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="run folders of `microconveyor train`")
    p.add_argument("--plot", type=plot_path, default=None, help="write the learning curves here")


@command("seeds", "aggregate training runs over seeds: IQM and bootstrap CI of the final "
                  "evaluations, learning curves", _seeds_args)
def cmd_seeds(args: argparse.Namespace) -> None:
    from ..plots.seeds import plot_curves
    from ..rl.evaluation.seeds import aggregate, curves

    res = aggregate(args.runs)
    res["curves"] = curves(args.runs)
    if args.plot:
        res["plot"] = plot_curves(res["curves"], args.plot)
    emit(args, res, "\n".join(iqm_lines(res, per_seed=True)))


def iqm_lines(agg: dict[str, Any], per_seed: bool) -> list[str]:
    """One line per aggregated figure of :func:`agents.rl.evaluation.seeds.aggregate` (IQM, 95 % CI and,
    with ``per_seed``, each run's value), in the units people read (%, µm)."""
    from microconveyor_env.cli.human import format_value

    def show(key: str, x: float) -> str:
        return format_value(key, x)[1]

    return [f"{format_value(k, 0.0)[0]}: IQM {show(k, v['iqm'])}, 95 % CI [{show(k, v['ci95'][0])}, "
            f"{show(k, v['ci95'][1])}]"
            + (f", per seed {', '.join(show(k, x) for x in v['per_seed'])}" if per_seed else "")
            for k, v in agg.items() if isinstance(v, dict) and "iqm" in v]
