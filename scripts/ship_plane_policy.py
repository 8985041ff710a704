"""Ship (or re-record) the PPO policy of a plane env: agents/policies/<env id>/ppo/.

    microconveyor train --env MicroConveyor2D-v0 --out DIR     # configs/ppo.yml's plane recipe
    python3 scripts/ship_plane_policy.py --run DIR             # ship that run's final policy
    python3 scripts/ship_plane_policy.py                       # re-record the shipped one
    python3 scripts/ship_plane_policy.py --env MicroConveyor2D-v1 [--run DIR]

``--run``: copies the run folder's ``model.zip``, ``normalization.json`` and ``metadata.json``.
Both: evaluates the folder as a user loads it (agents.rl.artefacts.policy_files, no pickle),
stores the summary in the metadata and every episode in ``episodes.json``, with the files' sha256
and how it was produced. MicroConveyor2D-v0: on the 100 fixed targets and on 1,000 others
(agents.rl.evaluation.evaluate). MicroConveyor2D-v1 (trained under per-episode randomisation):
on 1,000 held-out targets (seed 10,000 for the targets and the episodes' draws; a training of
seed s seeds its sub-envs s, s + 1, ...), under the randomisation it was trained with
(``evaluation``) and with it off (``evaluation_nominal``), the same targets.
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agents.rl.artefacts.checkpoint import META, replace_files, sha256  # noqa: E402
from agents.rl.artefacts.folders import fsync_dir, occupied, write_file  # noqa: E402
from agents.rl.artefacts.policy_files import (  # noqa: E402
    Policy,
    load_policy,
    policy_env_kwargs,
    required_files,
)
from agents.rl.artefacts.shipped import provenance, shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import (  # noqa: E402
    PLANE_TARGET_SEED,
    figures,
    fixed_targets,
    plane_record,
    rollout,
)

from microconveyor_env.envs.plane.config import PlaneEnvConfig  # noqa: E402
from microconveyor_env.envs.versions import PLANE_ENV_IDS, scene_config  # noqa: E402

ENV_ID = "MicroConveyor2D-v0"
RANDOMISED_ID = "MicroConveyor2D-v1"
HELD_OUT_SEED = 10_000   # v1's evaluation: targets and episode draws (sub-env i: seed + i)
HELD_OUT_TARGETS = 1000
EPISODES = "episodes.json"
NOTE = ("PPO on the plane (configs/ppo.yml's MicroConveyor2D-v0 recipe, one core). On the 100 "
        "fixed targets: {success:.0%} at rest within +-50 um (Euclidean), median {median:.1f} um, "
        "one forward pass per firing (README, 'In the plane').")


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
    replaced one by one, the model last (:func:`~agents.rl.artefacts.checkpoint.replace_files`:
    a folder caught in between holds no model and loads as no policy, never as a mixed one)."""
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


def ship(run: Path, folder: Path) -> None:
    """Copy the policy of the run folder ``run`` (loaded first: a complete, consistent policy
    folder, hashes verified) to ``folder``, which loads at every step but a kill's."""
    pol, meta = loaded_metadata(run)
    place_policy(run, meta, pol.metadata["files"], folder)


def record(folder: Path) -> dict:
    pol, meta = loaded_metadata(folder)
    cfg = pol.config
    assert isinstance(cfg, PlaneEnvConfig), f"{folder} holds no policy of the plane"
    episodes = {}
    # "evaluation": the 100 fixed targets of the README; "evaluation_fresh": 1,000 other targets
    # (another seed), the larger check (slow test)
    for key, n, seed in (("evaluation", 100, PLANE_TARGET_SEED), ("evaluation_fresh", 1000, 1)):
        res = rollout(pol, fixed_targets(cfg, n, seed), cfg)
        s = plane_record(figures(res, cfg.tolerance))
        meta[key] = {**s, "seed": seed, "target_box_m": cfg.grid_box, "config": "nominal"}
        episodes[key] = {"config": "nominal", "seed": seed, "target_m": res["targets_m"].tolist(),
                         "error_m": res["error_m"].tolist(), "outcome": res["outcome"].tolist(),
                         "firings": res["firings"].tolist()}
        if key == "evaluation":
            summary = s
    meta.setdefault("note", NOTE.format(success=summary["success_rate"],
                                        median=summary["median_error_m"] * 1e6))
    prov = provenance()
    prov["command"] = "python3 scripts/ship_plane_policy.py"
    meta["evaluation_provenance"] = prov
    write_records(folder, pol, meta, episodes)
    return summary


RANDOMISED_NOTE = (
    "PPO on {env_id} (configs/ppo.yml's {env_id} recipe, seed {seed}, final checkpoint, one "
    "core), trained under per-episode randomisation: execution noise sigma = {sigma:g} (action "
    "units) on each firing's frequency, stroke and delay, friction and mass factors drawn in "
    "{ff} and {mf}. 'evaluation' is at that level on {n:,} held-out targets (seed {eval_seed}), "
    "'evaluation_nominal' on the same targets without randomisation. One forward pass per "
    "firing; its observation does not show the episode's factors.")


def record_randomised(folder: Path) -> dict:
    """Record a policy trained under randomisation: ``evaluation`` under its training
    randomisation, ``evaluation_nominal`` without, on the same held-out targets."""
    pol, meta = loaded_metadata(folder)
    nominal_cfg = pol.config
    trained = scene_config(pol.env_id, **policy_env_kwargs(meta))
    assert isinstance(nominal_cfg, PlaneEnvConfig) and isinstance(trained, PlaneEnvConfig), \
        f"{folder} holds no policy of the plane"
    episodes = {}
    seed, n = HELD_OUT_SEED, HELD_OUT_TARGETS
    for key, cfg, label in (("evaluation", trained, "trained"),
                            ("evaluation_nominal", nominal_cfg, "nominal")):
        targets = fixed_targets(cfg, n, seed)
        res = rollout(pol, targets, cfg, seed=seed)
        s = plane_record(figures(res, cfg.tolerance))
        level = {"action_noise": cfg.action_noise,
                 "friction_factor_range": list(cfg.friction_factor_range),
                 "mass_factor_range": list(cfg.mass_factor_range)}
        meta[key] = {**s, "seed": seed, "target_box_m": cfg.grid_box, "config": label, **level}
        ep = {"config": label, "seed": seed, **level, "target_m": res["targets_m"].tolist(),
              "error_m": res["error_m"].tolist(), "outcome": res["outcome"].tolist(),
              "firings": res["firings"].tolist()}
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
    prov = provenance()
    prov["command"] = f"python3 scripts/ship_plane_policy.py --env {pol.env_id}"
    meta["evaluation_provenance"] = prov
    write_records(folder, pol, meta, episodes)
    return {"evaluation": meta["evaluation"], "evaluation_nominal": meta["evaluation_nominal"]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", default=None,
                   help="a `microconveyor train --env ID` run folder to ship")
    p.add_argument("--env", default=ENV_ID, choices=PLANE_ENV_IDS,
                   help=f"the plane env id (default {ENV_ID})")
    args = p.parse_args()
    folder = shipped_path("ppo", args.env)
    if args.run:
        ship(Path(args.run), folder)
    summary = record(folder) if args.env == ENV_ID else record_randomised(folder)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
