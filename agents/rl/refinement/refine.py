"""Refining a trained policy's aim on the simulator: Newton corrections of its last firing, and of
its first firing alone where it overshoots a near target, fitted back into the actor (one form of
expert iteration; ``microconveyor refine``).

Why: on MicroConveyor-v1 PPO's final policies miss the ±50 µm bar by errors that are smooth in the
target (a bias of 40-70 µm over a band of far targets, a median of 20-30 µm) and by near targets
(0.5-0.9 mm) whose first firing already carries the part past; the end of a PPO run is a draw
around the bar (docs/agents.md). The env is deterministic at its defaults and a firing costs
~10 µs, so the policy's own episodes can be corrected on the simulator itself and the corrections
taught back to the network. Each round:

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
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, NamedTuple
from collections.abc import Callable

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorVectorEnv
from microconveyor_env.envs.versions import GOAL_ENV_IDS

from ..artefacts.policy_files import Policy, policy_scene

CURVE = "evaluations.jsonl"   # a train run's learning curve (agents.rl.training.train)
CURVE_LIMIT = 64 << 20        # bytes of it read from a source folder
TARGET_SEED_SALT = 0x5EF1  # training targets: default_rng([seed, salt]), never an evaluation set


@dataclass(frozen=True)
class RefineSettings:
    """``targets`` [-] training targets per round; ``rounds`` [-] correct-and-fit rounds;
    ``newton_iterations`` [-] on the last firing, ``first_iterations`` [-] on the first firing
    alone, per round; ``step`` [action units] forward-difference step;
    ``max_step`` [action units] largest Newton step; ``accept_m`` [m] a corrected episode is kept
    when it ends this close; ``fit_iterations`` [-] L-BFGS iterations per fit; ``seed`` [-] of the
    training targets."""

    targets: int = 1000
    rounds: int = 8
    newton_iterations: int = 6
    first_iterations: int = 12
    step: float = 1e-3
    max_step: float = 0.2
    accept_m: float = 10e-6
    fit_iterations: int = 1000
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("targets", "rounds", "newton_iterations", "first_iterations",
                     "fit_iterations"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
                raise ValueError(f"refine: {name} must be an integer >= 1, got {value!r}")
        for name in ("step", "max_step", "accept_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"refine: {name} must be a positive number, got {value!r}")


class Episodes(NamedTuple):
    """Deterministic episodes of a batch (arrays over it): signed final error [m] (NaN: not
    ended), at rest, the raw observation before each firing ``(B, n, obs)``, the action taken
    (pre-clip) ``(B, n, 3)`` and whether firing ``k`` was taken ``(B, n)``."""

    error_m: np.ndarray
    rest: np.ndarray
    obs: np.ndarray
    actions: np.ndarray
    taken: np.ndarray


class Actor:
    """The mean action of a Gaussian actor (PPO's) *before* the env's clipping, for a batch of
    raw observations (normalised as in training); ``net`` is the torch module fitted."""

    def __init__(self, policy: Policy) -> None:
        self.policy_actor = policy.actor
        self.net = policy.actor.module
        self.normalizer = policy.normalizer

    def features(self, obs: np.ndarray) -> Any:
        import torch

        x = self.normalizer(obs) if self.normalizer is not None else obs.astype(np.float32)
        return torch.as_tensor(x, dtype=torch.float32)

    def mean(self, x: Any) -> Any:
        return self.policy_actor.mean(x)

    def raw(self, obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            return self.mean(self.features(obs)).numpy().astype(np.float32)


def play(config: EnvConfig, targets: np.ndarray, actor: Actor | None = None,
         plans: np.ndarray | None = None) -> Episodes:
    """One deterministic episode per target: closed loop with ``actor`` or open loop with
    ``plans`` ``(B, n_actuators, 3)`` (pre-clip; the env sees them clipped to the box)."""
    n, b = config.n_actuators, len(targets)
    env = MicroConveyorVectorEnv(b, config=config, autoreset_mode="SameStep")
    try:
        obs, _ = env.reset(seed=0, options={"target": np.asarray(targets, float)})
        done = np.zeros(b, bool)
        err, rest = np.full(b, np.nan), np.zeros(b, bool)
        O = np.zeros((b, n, obs.shape[1]), np.float32)
        A = np.zeros((b, n, 3), np.float32)
        taken = np.zeros((b, n), bool)
        for k in range(n):
            a = actor.raw(obs) if actor is not None else np.asarray(plans)[:, k].astype(np.float32)
            O[:, k], A[:, k], taken[:, k] = obs, a, ~done
            obs, _, term, trunc, info = env.step(np.clip(a, -1.0, 1.0))
            src = info.get("final_info", info)
            new = (term | trunc) & ~done
            err[new] = src["position_error_m"][new]
            rest[new] = src["outcome"][new] == "rest"
            done |= term | trunc
            if done.all():
                break
    finally:
        env.close()
    return Episodes(err, rest, O, A, taken)


NOOP = np.array([-1.0, -1.0, 1.0], np.float32)   # 200 Hz, 100 um after 0.1 s: a part stays put


def _newton(config: EnvConfig, targets: np.ndarray, plans: np.ndarray, firing: np.ndarray,
            settings: RefineSettings, iterations: int, box: float | None = None,
            taken: np.ndarray | None = None) -> np.ndarray:
    """Gauss-Newton on firing ``firing[i]`` of each open-loop plan ``(B, n, 3)``: forward
    differences of the final error with respect to its three actions, minimal-norm steps that
    zero it, capped at ``settings.max_step``. With ``box``, the firing stays within [-box, box]
    (inside the env's box, so the differences see the firing the env fires). With ``taken``, a
    plan whose episode no longer takes those firings is not stepped."""
    b = len(targets)
    rows, plans = np.arange(b), plans.copy()
    for _ in range(iterations):
        base = play(config, targets, plans=plans)
        grad = np.zeros((b, 3))
        for j in range(3):
            probe = plans.copy()
            probe[rows, firing, j] += settings.step
            grad[:, j] = (play(config, targets, plans=probe).error_m - base.error_m) / settings.step
        usable = (base.rest & np.isfinite(base.error_m) & np.isfinite(grad).all(1)
                  & ((grad ** 2).sum(1) > 0))
        if taken is not None:
            usable &= (base.taken == taken).all(1)
        delta = np.zeros((b, 3))
        delta[usable] = (-base.error_m[usable, None] * grad[usable]
                         / (grad[usable] ** 2).sum(1, keepdims=True))
        norm = np.linalg.norm(delta, axis=1, keepdims=True)
        delta *= np.minimum(1.0, settings.max_step / np.maximum(norm, 1e-300))
        moved = plans[rows, firing] + delta.astype(np.float32)
        plans[rows, firing] = moved if box is None else np.clip(moved, -box, box)
    return plans


def correct_last_firing(config: EnvConfig, targets: np.ndarray, episodes: Episodes,
                        settings: RefineSettings) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton on the last firing of each episode in its pre-clip actions (module
    docstring, step 2). Returns the corrected plans ``(B, n, 3)`` and a mask of the episodes
    whose correction is kept (within ``accept_m``, better than its own, the same length)."""
    last = episodes.taken.sum(1) - 1
    plans = _newton(config, targets, episodes.actions, last, settings,
                    settings.newton_iterations, taken=episodes.taken)
    final = play(config, targets, plans=plans)
    own = np.where(episodes.rest, np.abs(episodes.error_m), np.inf)
    keep = (final.rest & (final.taken == episodes.taken).all(1)
            & (np.abs(final.error_m) <= settings.accept_m) & (np.abs(final.error_m) < own))
    return plans, keep


def correct_first_firing(config: EnvConfig, targets: np.ndarray, episodes: Episodes,
                         settings: RefineSettings) -> tuple[np.ndarray, np.ndarray]:
    """For each *failed* episode (not at rest within the scene's tolerance): Gauss-Newton on the
    first firing alone (the others no-ops, :data:`NOOP`), from its action clipped to the box, for
    a firing that leaves the part at the target (on v1's surface it lands targets up to
    ~1.6 mm; nearer ones need a weaker first firing than the policy's, which carries the part
    past them). Returns the plans and a mask of the episodes kept: the episode ends at the
    first firing (the env stops a delivered part) within ``accept_m``."""
    b, n = len(targets), config.n_actuators
    plans = np.repeat(NOOP[None, None], b, 0).repeat(n, 1)
    box = 1.0 - settings.step   # forward differences stay inside the box
    plans[:, 0] = np.clip(episodes.actions[:, 0], -box, box)
    plans = _newton(config, targets, plans, np.zeros(b, int), settings,
                    settings.first_iterations, box=box)
    final = play(config, targets, plans=plans)
    failed = ~(episodes.rest & (np.abs(episodes.error_m) <= config.tolerance))
    keep = (failed & final.rest & (final.taken.sum(1) == 1)
            & (np.abs(final.error_m) <= settings.accept_m))
    return plans, keep


def labelled_episodes(config: EnvConfig, targets: np.ndarray, episodes: Episodes,
                      settings: RefineSettings) -> tuple[Episodes, np.ndarray, np.ndarray]:
    """The episodes the actor is fitted to: a failed episode the first firing alone lands
    replaced by that one-firing episode, else one with a kept last-firing correction by the
    corrected one, else itself; played open loop, so every label sits at the state its
    episode visits. Returns them and the two kept masks."""
    last_plans, last_kept = correct_last_firing(config, targets, episodes, settings)
    first_plans, first_kept = correct_first_firing(config, targets, episodes, settings)
    last_kept &= ~first_kept
    plans = np.where(first_kept[:, None, None], first_plans,
                     np.where(last_kept[:, None, None], last_plans, episodes.actions))
    return play(config, targets, plans=plans), last_kept, first_kept


def fit(actor: Actor, obs: np.ndarray, actions: np.ndarray, iterations: int) -> tuple[float, float]:
    """Fit the actor's mean to ``actions`` at ``obs`` (rows of a batch) as the env fires them:
    both clipped to the box, so a mean beyond the box whose label is beyond it too costs nothing.
    Full-batch L-BFGS in float64 (the fit must resolve action changes of ~1e-3, which move a far
    target's landing by tens of µm); the weights go back to float32. Returns the mean squared
    error [action units²] before and after."""
    import torch

    net = actor.net
    params = list(net.parameters())
    net.to(torch.float64)
    try:
        x = actor.features(obs).to(torch.float64)
        y = torch.as_tensor(np.clip(actions, -1.0, 1.0), dtype=torch.float64)

        def loss() -> Any:
            return ((actor.mean(x).clamp(-1.0, 1.0) - y) ** 2).sum(1).mean()

        with torch.no_grad():
            before = float(loss())
        opt = torch.optim.LBFGS(params, lr=1.0, max_iter=iterations, history_size=50,
                                line_search_fn="strong_wolfe", tolerance_grad=1e-12,
                                tolerance_change=1e-14)

        def closure() -> Any:
            opt.zero_grad()
            value = loss()
            value.backward()
            return value

        opt.step(closure)
        with torch.no_grad():
            after = float(loss())
    finally:
        net.to(torch.float32)
    return before, after


def _score(config: EnvConfig, targets: np.ndarray, actor: Actor) -> dict[str, float]:
    ep = play(config, targets, actor=actor)
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
    actor = Actor(policy)
    low, high = cfg.target_range
    targets = np.random.default_rng([s.seed, TARGET_SEED_SALT]).uniform(low, high, s.targets)
    best_state = copy.deepcopy(actor.net.state_dict())
    best = _score(cfg, targets, actor)
    kept, rounds = 0, [{"round": 0, "training_score": best}]
    emit = log or (lambda line: None)
    emit(f"refine: {s.targets} training targets, as given: {_line(best, cfg)}")
    for r in range(1, s.rounds + 1):
        ep = play(cfg, targets, actor=actor)
        lab, last_kept, first_kept = labelled_episodes(cfg, targets, ep, s)
        before, after = fit(actor, lab.obs[lab.taken], lab.actions[lab.taken], s.fit_iterations)
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


def write_refined(policy: Policy, report: dict[str, Any], out: str | Path,
                  evaluation: dict[str, Any] | None = None) -> Path:
    """Write the refined ``policy`` as a policy folder ``out`` (which must not exist or be
    empty): its model zip with the new actor's tensors in ``policy.pth`` (every other tensor and
    entry copied unchanged; the optimizer state is the training's and is not used by
    evaluation), its ``normalization.json`` unchanged, and ``metadata.json`` with
    ``refinement`` (``report``), ``refined_from`` (the source's evaluation and file hashes) and
    ``evaluation``; a train run's ``evaluations.jsonl`` is copied with the refined evaluation
    appended. The source's files are read as a received folder's are (regular files within
    limits, plain entry names). Written in a temporary folder beside ``out``, verified and
    renamed into place: a kill leaves no half folder, and a later write removes what a killed
    one left."""
    import io
    import json
    import shutil
    import zipfile

    import torch

    from microconveyor_env.safe_files import read_bytes, read_text

    from ..artefacts.checkpoint import (
        META,
        MODEL,
        NORMALIZATION,
        check_new_folder,
        read_meta,
        sha256,
        stale_temporaries,
        verify_files,
    )
    from ..artefacts.normalization import NORMALIZATION_LIMIT
    from ..artefacts.sb3_files import open_model, read_weights

    out = Path(out)
    check_new_folder(out)
    src = Path(policy.path)
    for old_tmp in stale_temporaries(out.parent, f".{out.name}.tmp-"):
        shutil.rmtree(old_tmp, ignore_errors=True)
    zin = open_model(src / MODEL)
    state = read_weights(src / MODEL, "policy.pth", zin)
    fitted = policy.actor.sb3_state()
    missing = sorted(set(fitted) - set(state))
    if missing:
        raise ValueError(f"{str(src / MODEL)!r}: policy.pth has no {missing}")
    state.update(fitted)
    weights = io.BytesIO()
    torch.save(state, weights)
    curve = None
    if (src / CURVE).exists() and evaluation is not None:
        curve = read_text(CURVE, CURVE_LIMIT, src)
    norm = (read_bytes(NORMALIZATION, NORMALIZATION_LIMIT, src)
            if (src / NORMALIZATION).exists() or (src / NORMALIZATION).is_symlink() else None)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        with zipfile.ZipFile(tmp / MODEL, "w") as zout:
            for name, item in zin.infos.items():
                zout.writestr(item, weights.getvalue() if name == "policy.pth" else zin.read(name))
        if norm is not None:
            (tmp / NORMALIZATION).write_bytes(norm)
        if curve is not None and evaluation is not None:
            # a train run's learning curve, ending with the refined policy's point: the same
            # steps, the training's wall time plus the refinement's (`microconveyor seeds`)
            row = {**evaluation, "steps": policy.metadata.get("steps"), "refined": True,
                   "wall_time_s": float(policy.metadata.get("wall_time_s") or 0.0)
                   + float(report["wall_time_s"])}
            (tmp / CURVE).write_text(curve.rstrip("\n") + "\n" + json.dumps(row) + "\n")
        old = dict(policy.metadata)
        for key in ("note", "evaluation_fresh", "evaluation_provenance"):
            old.pop(key, None)   # they describe the weights before refinement
        meta = {**old, "refinement": report,
                "refined_from": {"path": str(src), "files": policy.metadata.get("files"),
                                 "evaluation": policy.metadata.get("evaluation")},
                "evaluation": evaluation,
                "files": {p.name: sha256(p) for p in sorted(tmp.iterdir()) if p.is_file()}}
        (tmp / META).write_text(json.dumps(meta, indent=2, default=str) + "\n")
        verify_files(tmp, read_meta(tmp))
        if out.exists():
            out.rmdir()
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
