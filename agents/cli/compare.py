"""The ``microconveyor compare`` command: its options, turned into one
:class:`~agents.experiments.compare_settings.CompareSettings` (:func:`settings_of`), the run, its
charts and its summary."""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microconveyor_env.cli.base import (command, companion, emit, plot_path, settings_from,
                                        settings_options)
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, budgets, env_config_of, env_kwargs_of, levels

if TYPE_CHECKING:
    from ..experiments.compare_settings import CompareSettings

# --quick: a short look (README, tests): fewer targets, one small budget, a cheap MPC
QUICK: dict[str, Any] = {"targets": 20, "budgets": [300], "mpc_budgets": (100, 50)}


def pairs(text: str) -> list[tuple[float, float]]:
    """``σ:r`` pairs, comma-separated (e.g. ``1e-3:0.01,3e-3:0.05``), each value >= 0."""
    out = []
    for item in (t.strip() for t in text.split(",") if t.strip()):
        a, sep, b = item.partition(":")
        try:
            pair = (float(a), float(b))
        except ValueError:
            pair = (-1.0, -1.0)
        if not sep or min(pair) < 0 or not all(map(lambda v: v < float("inf"), pair)):
            raise argparse.ArgumentTypeError(f"{item!r}: give SIGMA:R with numbers >= 0, "
                                             "e.g. 3e-3:0.05")
        out.append(pair)
    return out


def mpc_budgets(text: str) -> tuple[int, int]:
    """``FIRST,REPLAN`` episodes of the model (each >= 10), or 0 for no MPC (``(0, 0)``)."""
    if text.strip() == "0":
        return 0, 0
    vals = text.split(",")
    try:
        first, replan = (int(float(v)) for v in vals)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give FIRST,REPLAN (e.g. 1000,300) or 0"
                                         ) from None
    if min(first, replan) < 10:
        raise argparse.ArgumentTypeError(f"{text!r}: MPC budgets must be >= 10 episodes")
    return first, replan


def names(text: str) -> list[str]:
    """A comma list of names (spaces around them dropped)."""
    return [m.strip() for m in text.split(",") if m.strip()]


def add_args(p: argparse.ArgumentParser) -> None:
    from ..experiments.compare_settings import (MPC_SETTINGS, ROBUST_MPC_SETTINGS,
                                                CompareSettings)

    def options(*fields: str) -> None:
        settings_options(p, CompareSettings, list(fields), unset=("n_targets", "budgets"),
                         parse={"budgets": budgets, "methods": names, "noise_ladder": levels,
                                "spread_ladder": levels, "diagonal": pairs,
                                "mpc_models": names},
                         help_={"n_targets": "number of fixed targets (drawn with --seed from "
                                             "the default range; default {default}, --quick "
                                             f"{QUICK['targets']})",
                                "budgets": "episodes per target for DE and CMA-ES (comma list; "
                                           "default {default}, --quick "
                                           f"{','.join(map(str, QUICK['budgets']))})"})

    options("n_targets", "seed", "budgets", "methods")
    p.add_argument("--mpc-budgets", type=mpc_budgets, default=None, metavar="FIRST,REPLAN",
                   help="MPC: episodes of the model before the first firing and per re-plan "
                        f"(default {MPC_SETTINGS.first_budget},{MPC_SETTINGS.replan_budget}, "
                        "--quick 100,50; 0: no MPC)")
    p.add_argument("--mpc-method", choices=("de", "cmaes"), default=None,
                   help="the MPC's planner (default: de; not with --mpc-budgets 0)")
    p.add_argument("--robust-mpc", type=mpc_budgets, nargs="?", default=None,
                   const=(ROBUST_MPC_SETTINGS.first_budget, ROBUST_MPC_SETTINGS.replan_budget),
                   metavar="FIRST,REPLAN",
                   help="also the robust, adaptive MPC: 8 noisy copies per candidate at σ=3e-3, "
                        "friction and mass identified online (budgets default "
                        f"{ROBUST_MPC_SETTINGS.first_budget},{ROBUST_MPC_SETTINGS.replan_budget}"
                        ": ~5x the MPC's compute)")
    p.add_argument("--mpc-prior", default=None, metavar="POLICY",
                   help="a policy folder ('shipped': the env's default shipped policy) whose "
                        "plan on the "
                        "model seeds the MPC's searches: adds the method mpc_<folder name> "
                        "(mpc_ppo_refined) and seeds the robust MPC")
    options("mpc_workers")
    p.add_argument("--policy", default=None,
                   help="the closed-loop policy's folder (default, 'shipped': the env's default "
                        f"shipped policy, {_defaults_text()}; on the positioner none if none is "
                        "shipped, '' to skip); its row is named after its folder "
                        "(ppo_refined, dagger, a run folder's name)"),
    p.add_argument("--randomised-policy", default=None,
                   help="PPO trained with randomisation (default: the shipped one; '' to skip)")
    options("policy_seeds", "noise_ladder", "spread_ladder", "diagonal", "mpc_models",
            "plan_firings", "full_grid")
    p.add_argument("--quick", action="store_true",
                   help="a short look: 20 targets, budget 300, MPC 100,50 (explicit options win)")
    options("perturb_repeats", "amortise_over")
    p.add_argument("--plot", type=plot_path, default=None,
                   help="chart file (success against tolerance); the compute, perturbation, "
                        "episodes-to-tolerance (and with --full grid) charts go beside it as "
                        "STEM_compute, STEM_perturbation, STEM_ecdf (STEM_grid), the result as "
                        "STEM.json")
    add_env_args(p, default=DEFAULT_ENV_ID,
                 what=" (a version of the conveyor line, or the positioner; the policies must "
                      "have been trained on its scene)")


def settings_of(args: Any) -> CompareSettings:
    """The :class:`~agents.experiments.compare_settings.CompareSettings` of the command line
    (``--quick`` fills what is not given; explicit options win); ValueError for an env id the
    comparison does not run on, before anything else is read."""
    from ..experiments.compare_settings import MPC_SETTINGS, CompareSettings, check_env_id
    from ..mpc import MPCSettings

    check_env_id(args.env)
    quick: dict[str, Any] = QUICK if args.quick else {}
    mb = args.mpc_budgets or quick.get("mpc_budgets") or (MPC_SETTINGS.first_budget,
                                                          MPC_SETTINGS.replan_budget)
    if mb == (0, 0) and args.mpc_method is not None:
        raise ValueError("--mpc-method chooses the MPC's planner; --mpc-budgets 0 runs no MPC")
    mpc = None if mb == (0, 0) else MPCSettings(method=args.mpc_method or "de",
                                                 first_budget=mb[0], replan_budget=mb[1],
                                                 seed=args.seed)
    filled = {k: quick[q] for k, q in (("n_targets", "targets"), ("budgets", "budgets"))
              if getattr(args, k) is None and q in quick}   # else the settings' defaults
    return settings_from(
        CompareSettings, args, **filled, env_id=args.env, config=_config(args),
        policy=None if args.policy == "shipped" else args.policy,
        randomised_policy=args.randomised_policy, mpc=mpc,
        robust_mpc=_robust(args.robust_mpc, args.seed),
        mpc_prior=_prior(args.mpc_prior, args.env))


def run(args: Any) -> None:
    from microconveyor_env.cli.base import json_default

    from ..experiments.compare import compare
    from ..experiments.compare_text import summary_table
    from ..plots.compare import plot_all

    res = compare(settings_of(args))
    res.update(env_id=args.env, env_kwargs=env_kwargs_of(args))
    if args.plot:
        res["charts"] = plot_all(res, args.plot, companion(args.plot, "compute"),
                                 companion(args.plot, "perturbation"),
                                 companion(args.plot, "ecdf"), companion(args.plot, "grid"))
        out = Path(args.plot).with_suffix(".json")
        out.write_text(json.dumps(res, indent=1, default=json_default))
        res["charts"].append(str(out))
    text = summary_table(res)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, res, text + "".join(f"\nwrote {c}" for c in res.get("charts", [])))
    lost = sum(r.get("lost_episodes", 0) for r in res["rows"])
    if res.get("mpc_worker_deaths"):
        raise ValueError(f"an MPC worker process died {res['mpc_worker_deaths']} time(s): its "
                         f"episodes ran again in processes of their own ({lost} lost when that "
                         "process died too, counted as failures above)")


def _config(args: Any) -> Any:
    """The config of ``--env`` with ``--env-kwargs``: the line's EnvConfig, or the scene's own
    config (the positioner's)."""
    from microconveyor_env.env_ids import REGISTRY
    from microconveyor_env.envs.core.versions import scene_config

    if REGISTRY[args.env].geometry == "line":
        return env_config_of(args, args.env)
    return scene_config(args.env, **env_kwargs_of(args))


def _robust(budgets: tuple[int, int] | None, seed: int) -> Any:
    from ..experiments.compare_settings import ROBUST_MPC_SETTINGS

    if budgets is None or budgets == (0, 0):
        return None
    return dataclasses.replace(ROBUST_MPC_SETTINGS, first_budget=budgets[0],
                               replan_budget=budgets[1], seed=seed)


def _prior(given: str | None, env_id: str) -> str | None:
    from ..rl.artefacts.shipped import require_shipped

    if given is None:
        return None
    path = require_shipped(env_id) if given == "shipped" else Path(given)   # the id's default
    if not (Path(path) / "model.zip").is_file():
        raise ValueError(f"--mpc-prior {given!r}: no policy folder (model.zip) there")
    return str(path)


def _defaults_text() -> str:
    """The default shipped policy of every id compare runs on, in words."""
    from microconveyor_env.env_ids import REGISTRY

    from ..experiments.compare_settings import GEOMETRIES
    from ..rl.artefacts.shipped import default_policy_name

    return ", ".join(f"{default_policy_name(i)} on {i}" for i, r in REGISTRY.items()
                     if r.geometry in GEOMETRIES and r.base == i)


def _compare_args(p: argparse.ArgumentParser) -> None:
    add_args(p)


@command("compare", "closed loop vs open loop on fixed targets: the env's default shipped policy "
                    "and PPO trained with randomisation, model-predictive control, DE and "
                    "CMA-ES, a random policy "
                    "and a fixed schedule; accuracy vs compute, success vs tolerance, episodes "
                    "to the tolerance, success vs perturbation (noise, model error, both)",
         _compare_args)
def cmd_compare(args: Any) -> None:
    run(args)
