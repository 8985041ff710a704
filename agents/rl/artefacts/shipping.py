"""Shipping a trained policy and recording the shipped policies' evaluations.

A shipped policy is a folder ``<root>/<env id>/<name>/`` (``root``: ``agents/policies`` of the
package, :func:`~.shipped.shipped_path`) holding ``model.zip``, ``normalization.json``,
``metadata.json`` and ``episodes.json``. :func:`record` evaluates it on its fixed targets and
writes the summaries (errors, success and placement times) into ``metadata.json`` and every
episode into ``episodes.json``, with how they were produced (:func:`~.shipped.provenance`);
:func:`ship` copies a training run folder's policy there and names the records to make. The
commands: ``microconveyor ship`` and ``microconveyor record`` (:mod:`agents.cli.ship`).

What each folder records:

* the line and the positioner: the records its metadata names, each re-evaluated on its own
  number of targets and seed (:data:`EVALUATIONS` for the names shipped first; a newly shipped
  policy gets :data:`NEW_RECORDS`), ``"nominal"`` with the scene's randomisation off,
  ``"trained"`` under the randomisation it was trained with;
* MicroConveyor2D-v0: ``evaluation`` on the 100 fixed targets (seed
  :data:`~agents.rl.evaluation.evaluate.PLANE_TARGET_SEED`) and ``evaluation_fresh`` on 1,000
  others (seed 1), nominal;
* any other plane id (trained under per-episode randomisation): ``evaluation`` under that
  randomisation and ``evaluation_nominal`` without it, on the same :data:`HELD_OUT_TARGETS`
  held-out targets (seed :data:`HELD_OUT_SEED` for the targets and the episodes' draws).

A folder is loaded as a user loads it (data only, every file's sha256 verified) before anything
in it changes, so a folder that does not load is refused untouched; the records and the metadata,
with the sha256 of the files the loader reads (``files``: without them it refuses the folder),
are each written whole (:func:`~.folders.write_file`: a temporary file and an atomic rename), the
metadata last, and the folder is loaded again. A policy is shipped by staging its files beside the
destination and loading them there before anything is replaced.
"""
from __future__ import annotations

import copy
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

from microconveyor_env.env_ids import PLANE_ENV_IDS
from microconveyor_env.envs import PlaneEnvConfig

from ..evaluation.evaluate import (
    PLANE_TARGET_SEED,
    figures,
    fixed_targets,
    placement_times,
    plane_record,
    rollout,
    summarize,
)
from .checkpoint import META, replace_files, sha256
from .folders import fsync_dir, occupied, write_file
from .policy_files import Policy, load_policy, policy_env_kwargs, policy_scene, required_files
from .shipped import provenance, shipped_path

__all__ = ["EPISODES", "EVALUATIONS", "NEW_RECORDS", "PLANE_ENV_ID", "HELD_OUT_SEED",
           "HELD_OUT_TARGETS", "loaded_metadata", "write_records", "place_policy", "ship",
           "record", "record_line", "record_plane", "record_randomised_plane", "policy_folder"]

EPISODES = "episodes.json"
# policy name -> {record: which env config ("nominal": the trained scene without randomisation,
# "trained": with the run's randomisation)}
EVALUATIONS = {"ppo": {"evaluation": "nominal", "evaluation_fresh": "nominal"},
               "ppo_refined": {"evaluation": "nominal", "evaluation_fresh": "nominal"},
               "ppo_randomised": {"evaluation": "trained", "evaluation_nominal": "nominal"}}
# what a newly shipped policy of the line or the positioner records (a policy not in
# EVALUATIONS re-records those its metadata holds): record -> (targets, target seed, env
# config); seed 12345 is the set training monitors, seed 1 a held-out one
NEW_RECORDS = {"evaluation": (100, 12345, "trained"),
               "evaluation_nominal": (100, 12345, "nominal"),
               "evaluation_fresh": (1000, 1, "trained")}
PLANE_ENV_ID = "MicroConveyor2D-v0"   # the plane trained without randomisation
HELD_OUT_SEED = 10_000   # a randomised plane's records: targets and episode draws (sub-env i: +i)
HELD_OUT_TARGETS = 1000
PLANE_NOTE = ("PPO on the plane (configs/ppo.yml's MicroConveyor2D-v0 recipe, one core). On the "
              "100 fixed targets: {success:.0%} at rest within +-50 um (Euclidean), median "
              "{median:.1f} um, one forward pass per firing (README, 'In the plane').")
RANDOMISED_NOTE = (
    "PPO on {env_id} (configs/ppo.yml's {env_id} recipe, seed {seed}, final checkpoint, one "
    "core), trained under per-episode randomisation: execution noise sigma = {sigma:g} (action "
    "units) on each firing's frequency, stroke and delay, friction and mass factors drawn in "
    "{ff} and {mf}. 'evaluation' is at that level on {n:,} held-out targets (seed {eval_seed}), "
    "'evaluation_nominal' on the same targets without randomisation. One forward pass per "
    "firing; its observation does not show the episode's factors.")


def policy_folder(env_id: str, name: str, root: str | Path | None = None) -> Path:
    """The folder of the shipped policy ``env_id/name``: under ``root`` (a folder laid out as
    ``agents/policies``), or the package's own (``root`` None)."""
    return shipped_path(name, env_id) if root is None else Path(root) / env_id / name


def command_line(env_id: str, name: str) -> str:
    """The command that records ``env_id/name`` (stored in its ``evaluation_provenance``)."""
    return f"microconveyor record {env_id}/{name}"


def loaded_metadata(folder: Path) -> tuple[Policy, dict[str, Any]]:
    """The policy at ``folder`` loaded as a user loads it (its files verified against its
    metadata; a folder that does not load is refused before anything is changed) and a copy of
    its metadata to record into."""
    pol = load_policy(folder)
    return pol, copy.deepcopy(pol.metadata)


def _listed(folder: Path, meta: dict[str, Any], verified: dict[str, Any]) -> dict[str, str]:
    """``files`` for ``meta``: the sha256 of every file the loader needs (and of any other file
    the verified metadata listed), each still the file that was verified (SystemExit if one
    changed meanwhile)."""
    files = {}
    for name in dict.fromkeys([*required_files(meta), *verified]):
        digest = sha256(folder / name)
        if name in verified and verified[name] != digest:
            raise SystemExit(f"{str(folder / name)!r} changed while it was evaluated; nothing "
                             "recorded")
        files[name] = digest
    return files


def write_records(folder: Path, pol: Policy, meta: dict[str, Any],
                  episodes: dict[str, Any]) -> None:
    """Write ``episodes.json`` and ``meta`` (``files`` recomputed) into the policy folder that
    ``pol`` was loaded from, each file whole (a temporary file and an atomic rename), the
    metadata last; then load the folder again (it must load as it did)."""
    meta["files"] = _listed(folder, meta, pol.metadata["files"])
    write_file(folder / EPISODES, json.dumps(episodes, indent=0) + "\n")
    write_file(folder / META, json.dumps(meta, indent=2) + "\n")
    load_policy(folder)


def place_policy(run: Path, meta: dict[str, Any], verified: dict[str, Any],
                 folder: Path) -> None:
    """Make ``folder`` the policy of the run folder ``run`` with the metadata ``meta``
    (``files`` recomputed; ``verified``: the run's files as its loading verified them): staged
    beside ``folder`` and loaded there first, then renamed into place (a new folder) or its files
    replaced one by one, the model last (:func:`~.checkpoint.replace_files`: a folder caught in
    between holds no model and loads as no policy, never as a mixed one)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    stage = folder.parent / f".{folder.name}.ship-{os.getpid()}"
    shutil.rmtree(stage, ignore_errors=True)
    stage.mkdir()
    try:
        names = tuple(required_files(meta))
        for name in names:
            shutil.copyfile(run / name, stage / name)
        meta = {**meta, "files": _listed(stage, meta, {n: verified[n] for n in names})}
        write_file(stage / META, json.dumps(meta, indent=2) + "\n")
        load_policy(stage)   # the staged folder loads before it replaces anything
        if not occupied(folder):
            if folder.is_dir():
                folder.rmdir()
            os.rename(stage, folder)
            fsync_dir(folder.parent)
        else:
            replace_files(stage, folder, (*names, META))
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    load_policy(folder)


def ship(run: str | Path, env_id: str, name: str, root: str | Path | None = None) -> Path:
    """Copy the policy of the training run folder ``run`` (``model.zip``, ``normalization.json``,
    ``metadata.json``; loaded first: a complete, consistent policy folder of ``env_id``, hashes
    verified) to the shipped folder ``env_id/name`` (:func:`policy_folder`), with the records
    :func:`record` is to make named in its metadata on the line and the positioner
    (:data:`NEW_RECORDS`). The new folder is staged and loaded before it replaces anything
    (:func:`place_policy`). Returns the folder; ValueError for a policy of another env."""
    pol, meta = loaded_metadata(Path(run))
    if meta.get("env_id") != env_id:
        raise ValueError(f"{run} holds a policy of {meta.get('env_id')!r}, not {env_id}")
    if env_id not in PLANE_ENV_IDS:
        randomised = getattr(policy_scene(meta), "randomised", False)
        for key, (n, seed, _) in NEW_RECORDS.items():
            if key == "evaluation_nominal" and not randomised:
                continue   # trained on the nominal scene: "evaluation" is that one
            meta[key] = {"n_targets": n, "seed": seed}
    folder = policy_folder(env_id, name, root)
    place_policy(Path(run), meta, pol.metadata["files"], folder)
    return folder


def _episodes(res: dict[str, Any], which: str, seed: int, **extra: Any) -> dict[str, Any]:
    """The record of every episode of ``res`` (:func:`~..evaluation.evaluate.rollout`): its
    target, error, outcome, firings and placement time ``time_s`` [s] (the simulated time until
    the part rested or detached)."""
    return {"config": which, "seed": seed, **extra, "target_m": res["targets_m"].tolist(),
            "error_m": res["error_m"].tolist(), "outcome": res["outcome"].tolist(),
            "firings": res["firings"].tolist(), "time_s": res["time_s"].tolist()}


def record_line(folder: Path, command: str) -> dict[str, Any]:
    """Re-record the evaluations of the line's or the positioner's policy at ``folder`` (module
    docstring); returns the new records' summaries."""
    pol, meta = loaded_metadata(folder)
    episodes = {}
    plan = EVALUATIONS.get(folder.name) or {k: v[2] for k, v in NEW_RECORDS.items() if k in meta}
    for key, which in plan.items():
        old = meta[key]
        # "trained": the scene and randomisation it was trained under; "nominal": randomisation off
        cfg = policy_scene(meta) if which == "trained" else pol.config
        if cfg is None or isinstance(cfg, PlaneEnvConfig):
            raise ValueError(f"{folder} holds no policy of the line or the positioner")
        targets = fixed_targets(cfg, old["n_targets"], old["seed"])
        res = rollout(pol, targets, cfg, seed=old["seed"])
        summary = {**summarize(res, cfg.tolerance),
                   **placement_times(res["time_s"], res["outcome"])}
        summary.update(seed=old["seed"], target_range_m=list(cfg.target_range), config=which)
        meta[key] = {**{k: v for k, v in old.items() if k in ("steps", "wall_time_s")}, **summary}
        episodes[key] = _episodes(res, which, old["seed"])
        print(f"{pol.env_id}/{folder.name} {key}: success {summary['success_rate_50um']:.3f}, "
              f"median {summary['median_abs_error_m'] * 1e6:.4f} um", file=sys.stderr)
    meta["format"] = 2
    meta["evaluation_provenance"] = provenance(command)
    write_records(folder, pol, meta, episodes)
    return {k: meta[k] for k in plan}


def record_plane(folder: Path, command: str) -> dict[str, Any]:
    """Record MicroConveyor2D-v0's policy at ``folder`` (module docstring); returns the summary
    on the 100 fixed targets."""
    pol, meta = loaded_metadata(folder)
    cfg = pol.config
    if not isinstance(cfg, PlaneEnvConfig):
        raise ValueError(f"{folder} holds no policy of the plane")
    episodes = {}
    summary: dict[str, Any] = {}
    # "evaluation": the 100 fixed targets of the README; "evaluation_fresh": 1,000 other targets
    # (another seed), the larger check (slow test)
    for key, n, seed in (("evaluation", 100, PLANE_TARGET_SEED), ("evaluation_fresh", 1000, 1)):
        res = rollout(pol, fixed_targets(cfg, n, seed), cfg)
        s = plane_record(figures(res, cfg.tolerance))
        meta[key] = {**s, "seed": seed, "target_box_m": cfg.grid_box, "config": "nominal"}
        episodes[key] = _episodes(res, "nominal", seed)
        if key == "evaluation":
            summary = s
    meta.setdefault("note", PLANE_NOTE.format(success=summary["success_rate"],
                                              median=summary["median_error_m"] * 1e6))
    meta["evaluation_provenance"] = provenance(command)
    write_records(folder, pol, meta, episodes)
    return summary


def record_randomised_plane(folder: Path, command: str) -> dict[str, Any]:
    """Record a plane policy trained under randomisation (module docstring): ``evaluation`` under
    its training randomisation, ``evaluation_nominal`` without, on the same held-out targets."""
    pol, meta = loaded_metadata(folder)
    nominal_cfg = pol.config
    trained = policy_scene(meta)
    if not (isinstance(nominal_cfg, PlaneEnvConfig) and isinstance(trained, PlaneEnvConfig)):
        raise ValueError(f"{folder} holds no policy of the plane")
    episodes = {}
    seed, n = HELD_OUT_SEED, HELD_OUT_TARGETS
    for key, cfg, label in (("evaluation", trained, "trained"),
                            ("evaluation_nominal", nominal_cfg, "nominal")):
        res = rollout(pol, fixed_targets(cfg, n, seed), cfg, seed=seed)
        s = plane_record(figures(res, cfg.tolerance))
        level = {"action_noise": cfg.action_noise,
                 "friction_factor_range": list(cfg.friction_factor_range),
                 "mass_factor_range": list(cfg.mass_factor_range)}
        meta[key] = {**s, "seed": seed, "target_box_m": cfg.grid_box, "config": label, **level}
        ep = _episodes(res, label, seed, **level)
        if cfg.randomised:
            ep["friction_factor"] = res["friction_factor"].tolist()
            ep["mass_factor"] = res["mass_factor"].tolist()
        episodes[key] = ep
    kw = policy_env_kwargs(meta)
    meta["note"] = RANDOMISED_NOTE.format(
        env_id=pol.env_id, seed=meta.get("seed"), sigma=trained.action_noise,
        ff=list(trained.friction_factor_range), mf=list(trained.mass_factor_range), n=n,
        eval_seed=seed)
    meta["env_kwargs"] = kw
    meta["evaluation_provenance"] = provenance(command)
    write_records(folder, pol, meta, episodes)
    return {"evaluation": meta["evaluation"], "evaluation_nominal": meta["evaluation_nominal"]}


def record(env_id: str, name: str, root: str | Path | None = None) -> dict[str, Any]:
    """Record the evaluations of the shipped policy ``env_id/name`` (under ``root``, default the
    package's ``agents/policies``) as its scene records them (module docstring); returns the
    new records' summaries."""
    folder = policy_folder(env_id, name, root)
    command = command_line(env_id, name)
    if env_id == PLANE_ENV_ID:
        return {"evaluation": record_plane(folder, command)}
    if env_id in PLANE_ENV_IDS:
        return record_randomised_plane(folder, command)
    return record_line(folder, command)
