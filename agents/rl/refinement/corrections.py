"""Newton corrections of a policy's episodes on the simulator (steps 1-3 of :mod:`.refine`):
its deterministic episodes (:func:`play`), Gauss-Newton on the last firing of each, and on the
first firing alone of each failed one, and the episodes the actor is fitted to."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorVectorEnv
from microconveyor_env.envs.core.episodes import PlanActor, run_episodes

from .fit import MeanActor
from .settings import RefineSettings


class Episodes(NamedTuple):
    """Deterministic episodes of a batch (arrays over it): signed final error [m] (NaN: not
    ended), at rest, the raw observation before each firing ``(B, n, obs)``, the action taken
    (pre-clip) ``(B, n, 3)`` and whether firing ``k`` was taken ``(B, n)``."""

    error_m: np.ndarray
    rest: np.ndarray
    obs: np.ndarray
    actions: np.ndarray
    taken: np.ndarray


def play(config: EnvConfig, targets: np.ndarray, actor: MeanActor | None = None,
         plans: np.ndarray | None = None) -> Episodes:
    """One deterministic episode per target: closed loop with ``actor`` or open loop with
    ``plans`` ``(B, n_actuators, 3)`` (pre-clip; the env sees them clipped to the box)."""
    n, b = config.n_actuators, len(targets)
    env = MicroConveyorVectorEnv(b, config=config, autoreset_mode="SameStep")
    try:
        ep = run_episodes(env, actor if actor is not None else PlanActor(np.asarray(plans)),
                          seed=0, options={"target": np.asarray(targets, float)}, max_steps=n,
                          clip=True, keep_steps=True)
    finally:
        env.close()
    assert ep.obs is not None and ep.actions is not None and ep.taken is not None
    return Episodes(ep.final["position_error_m"], ep.final["outcome"] == "rest", ep.obs,
                    ep.actions, ep.taken)


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
