"""The RL commands that read policies and runs: ``evaluate`` (a policy on a fixed, seeded set of
targets, on any registered env) and ``seeds`` (training runs aggregated over seeds)."""
from __future__ import annotations

import argparse
from typing import Any

from microconveyor_env.cli.base import command, count, emit, plot_path

from .args import add_env_args, env_kwargs_of, floats


def _evaluate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", default=None, help="policy folder or model zip (default: shipped)")
    p.add_argument("--targets", type=count(1, 100000), default=None,
                   help="number of targets drawn uniformly over the target range (default 100)")
    p.add_argument("--at", type=floats, default=None, metavar="D[,D...]",
                   help="evaluate at these distances [m] instead (the line's and the "
                        "positioner's), --per-distance targets over each d ± 0.1 mm, a row each; "
                        "e.g. 1e-3,3e-3,5e-3,7e-3,9e-3")
    p.add_argument("--per-distance", type=count(1, 10000), default=None,
                   help="with --at: targets per distance (default 5)")
    p.add_argument("--seed", type=count(0, 2**31 - 1), default=0,
                   help="seed of the fixed target set (and of the episodes)")
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
    from microconveyor_env.envs.core.versions import scene_config

    from ..rl.artefacts.policy_files import policy_env_kwargs, read_policy_meta
    from ..rl.artefacts.shipped import require_shipped
    from ..rl.evaluation.evaluate import evaluate, evaluate_at, load_policy

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
    if args.at is None:
        if args.per_distance is not None:
            raise ValueError("--per-distance goes with --at (the distances to evaluate at)")
        res = evaluate(pol, args.targets or 100, args.seed, args.tolerance, config=asked)
    else:
        if args.targets is not None:
            raise ValueError("--targets draws targets over the range; --at evaluates at given "
                             "distances: give one of them")
        res = evaluate_at(pol, args.at, args.per_distance or 5, args.seed, args.tolerance,
                          config=asked)
    res.update(policy=str(pol.path), env_id=pol.env_id, env_kwargs=kwargs,
               trained_env_kwargs=trained_kwargs)
    emit(args, res, "" if args.at is None else _per_distance_text(res))


def _ms(t_s: float | None) -> str:
    """A placement time [s] in ms; a dash where no part came to rest."""
    return "–" if t_s is None else f"{t_s * 1e3:.1f} ms"


def _per_distance_text(res: dict[str, Any]) -> str:
    """The per-distance rows of :func:`~agents.rl.evaluation.evaluate.evaluate_at` as a table in
    mm, µm, ms and %, then every target together: success, the error and the placement time
    (the simulated time until the part rests, over the parts that rested), median and 90th
    percentile."""
    within = f"within ±{res['tolerance_m'] * 1e6:g} µm"
    lines = [f"{res['env_id']}, policy {res['policy']}; {res['targets_per_distance']} targets "
             f"per distance over d ± 0.1 mm, seed {res['seed']}",
             f"{'distance':>9}  {within:>14}  {'median |error|':>14}  "
             f"{'p90 |error|':>11}  {'median time':>11}  {'p90 time':>9}  {'detached':>8}"]
    for r in [*res["per_distance"], {**res, "distance_m": None}]:
        d = "all" if r["distance_m"] is None else f"{r['distance_m'] * 1e3:g} mm"
        lines.append(f"{d:>9}  {r['success_rate']:>14.0%}  "
                     f"{r['median_abs_error_m'] * 1e6:>11.1f} µm  "
                     f"{r['p90_abs_error_m'] * 1e6:>8.1f} µm  "
                     f"{_ms(r['median_placement_time_s']):>11}  "
                     f"{_ms(r['p90_placement_time_s']):>9}  {r['detach_rate']:>8.0%}")
    return "\n".join(lines)


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
