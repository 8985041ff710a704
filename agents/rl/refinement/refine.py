"""Refining a trained policy's aim on the simulator: Newton corrections of its last firing, and of
its first firing alone where it overshoots a near target, fitted back into the actor (one form of
expert iteration; ``microconveyor refine``).

The env is deterministic at its defaults and a firing costs ~10 µs, so a policy's own episodes
can be corrected on the simulator itself and the corrections taught back to its network: the
errors it leaves are smooth in the target (a bias over a band of far targets) or come from near
targets whose first firing already carries the part past. Each round (the episodes:
:mod:`.corrections`; the actor and its fit: :mod:`.fit`; the folder written: :mod:`.writer`):

1. play the policy's deterministic episodes to ``targets`` training targets (drawn with ``seed``
   from the scene's target range, not the evaluation sets' seeds 12345 and 1);
2. for each episode that ends at rest, Gauss-Newton on the last firing it took: the final error's
   derivatives with respect to the firing's three *pre-clip* actions by forward differences,
   then the minimal-norm step that zeroes the error (capped at ``max_step``), ``newton_iterations``
   times. An action beyond the box is clipped by the env, has no derivative and stays where it
   is. A correction is kept when it lands within ``accept_m``, beats the episode's own error and
   ends the episode at the same firing;
3. for each *failed* episode, Gauss-Newton on the first firing alone (the later firings no-ops),
   from its action clipped into the box, ``first_iterations`` times; kept when the env stops the
   part after that one firing within ``accept_m`` (it then replaces step 2's correction);
4. fit the actor's mean (policy net and action head; the value net is not touched) to the
   corrected episodes' actions at their own states and to its own actions at every other state,
   both clipped to the box as the env fires them (full-batch L-BFGS in float64,
   ``fit_iterations``);
5. score the fitted actor on the training targets (success within the scene's tolerance, then
   median |error|).

The round with the best training score is kept, "round 0" being the policy as given, so a
refinement never leaves the policy worse on the targets it saw. Measured on ten seeds:
docs/agents.md, "Refining the aim".
"""
from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig
from microconveyor_env.env_ids import GOAL_ENV_IDS

from ..artefacts.policy_files import Policy, policy_scene
from . import corrections, fit as fitting
from .fit import MeanActor
from .settings import RefineSettings

TARGET_SEED_SALT = 0x5EF1  # training targets: default_rng([seed, salt]), never an evaluation set


def _score(config: EnvConfig, targets: np.ndarray, actor: MeanActor) -> dict[str, float]:
    ep = corrections.play(config, targets, actor=actor)
    err = np.abs(ep.error_m)
    return {"success_rate": float(np.mean(ep.rest & (err <= config.tolerance))),
            "median_abs_error_m": float(np.nanmedian(err))}


def _better(a: dict[str, float], b: dict[str, float]) -> bool:
    return (a["success_rate"], -a["median_abs_error_m"]) > (b["success_rate"],
                                                            -b["median_abs_error_m"])


def refine(policy: Policy, settings: RefineSettings | None = None,
           log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Refine ``policy`` (a loaded PPO/A2C policy of the 1-D conveyor) in place (module
    docstring) and return the report: the settings, each round's corrections, fit and training
    score, the round kept and the wall time [s]."""
    import torch

    s = settings or RefineSettings()
    cfg = policy.config
    if (not isinstance(cfg, EnvConfig) or policy.actor.algo not in ("ppo", "a2c")
            or policy.actor.squash or policy.actor.obs_keys is not None
            or policy.metadata.get("env_id") in GOAL_ENV_IDS):   # Dict observations
        raise ValueError("refine needs a policy of the 1-D conveyor (Box observations) with a "
                         f"Gaussian actor (PPO or A2C); {str(policy.path)!r} is not one")
    scene = policy_scene(policy.metadata) if policy.metadata else cfg
    if isinstance(scene, EnvConfig) and scene.randomised:
        raise ValueError(f"{str(policy.path)!r} was trained under per-episode randomisation "
                         "(docs/randomisation.md); refine corrects deterministic episodes and "
                         "would fit it to the nominal scene alone")
    t0 = time.perf_counter()
    actor = MeanActor(policy)
    low, high = cfg.target_range
    targets = np.random.default_rng([s.seed, TARGET_SEED_SALT]).uniform(low, high, s.targets)
    best_state = copy.deepcopy(actor.net.state_dict())
    best = _score(cfg, targets, actor)
    kept, rounds = 0, [{"round": 0, "training_score": best}]
    emit = log or (lambda line: None)
    emit(f"refine: {s.targets} training targets, as given: {_line(best, cfg)}")
    for r in range(1, s.rounds + 1):
        ep = corrections.play(cfg, targets, actor=actor)
        lab, last_kept, first_kept = corrections.labelled_episodes(cfg, targets, ep, s)
        before, after = fitting.fit(actor, lab.obs[lab.taken], lab.actions[lab.taken], s.fit_iterations)
        score = _score(cfg, targets, actor)
        rounds.append({"round": r, "corrected": int(last_kept.sum() + first_kept.sum()),
                       "corrected_last_firing": int(last_kept.sum()),
                       "corrected_first_firing": int(first_kept.sum()),
                       "fit_mse_before": before, "fit_mse_after": after,
                       "training_score": score})
        if _better(score, best):
            best, kept = score, r
            best_state = copy.deepcopy(actor.net.state_dict())
        emit(f"refine round {r}/{s.rounds}: {int(last_kept.sum())} last firings and "
             f"{int(first_kept.sum())} first firings corrected, "
             f"training targets {_line(score, cfg)} ({time.perf_counter() - t0:.0f} s)")
    with torch.no_grad():
        actor.net.load_state_dict(best_state)
    emit(f"refine: kept round {kept} ({_line(best, cfg)} on the training targets)")
    return {"settings": asdict(s), "rounds": rounds, "kept_round": kept,
            "wall_time_s": time.perf_counter() - t0}


def _line(score: dict[str, float], cfg: EnvConfig) -> str:
    return (f"{score['success_rate']:.1%} within {cfg.tolerance * 1e6:.0f} µm, median "
            f"{score['median_abs_error_m'] * 1e6:.1f} µm")
