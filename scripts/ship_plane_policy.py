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
import json
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agents.rl.artefacts.checkpoint import META, MODEL, NORMALIZATION, sha256  # noqa: E402
from agents.rl.artefacts.policy_files import load_policy, policy_env_kwargs  # noqa: E402
from agents.rl.artefacts.shipped import provenance, shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import (  # noqa: E402
    PLANE_TARGET_SEED,
    figures,
    fixed_targets,
    plane_record,
    rollout,
)

from microconveyor_env.envs.versions import PLANE_ENV_IDS, scene_config  # noqa: E402

ENV_ID = "MicroConveyor2D-v0"
RANDOMISED_ID = "MicroConveyor2D-v1"
HELD_OUT_SEED = 10_000   # v1's evaluation: targets and episode draws (sub-env i: seed + i)
HELD_OUT_TARGETS = 1000
EPISODES = "episodes.json"
NOTE = ("PPO on the plane (configs/ppo.yml's MicroConveyor2D-v0 recipe, one core). On the 100 "
        "fixed targets: {success:.0%} at rest within +-50 um (Euclidean), median {median:.1f} um, "
        "one forward pass per firing (README, 'In the plane').")


def ship(run: Path, folder: Path) -> None:
    load_policy(run)   # a complete, consistent policy folder (hashes verified)
    folder.mkdir(parents=True, exist_ok=True)
    for name in (MODEL, NORMALIZATION, META):
        shutil.copyfile(run / name, folder / name)


def record(folder: Path) -> dict:
    meta_path = folder / META
    meta = json.loads(meta_path.read_text())
    meta.pop("files", None)                      # re-hashed below
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    pol = load_policy(folder)
    cfg = pol.config
    assert cfg is not None
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
    meta["files"] = {n: sha256(folder / n) for n in (MODEL, NORMALIZATION)}
    (folder / EPISODES).write_text(json.dumps(episodes, indent=0) + "\n")
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
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
    meta_path = folder / META
    meta = json.loads(meta_path.read_text())
    meta.pop("files", None)                      # re-hashed below
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    pol = load_policy(folder)
    nominal_cfg = pol.config
    assert nominal_cfg is not None
    trained = scene_config(pol.env_id, **policy_env_kwargs(meta))
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
    meta["files"] = {name: sha256(folder / name) for name in (MODEL, NORMALIZATION)}
    (folder / EPISODES).write_text(json.dumps(episodes, indent=0) + "\n")
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
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
