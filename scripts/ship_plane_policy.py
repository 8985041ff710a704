"""Ship (or re-record) the PPO policy of MicroConveyor2D-v0: agents/policies/MicroConveyor2D-v0/ppo/.

    microconveyor train --env MicroConveyor2D-v0 --out DIR     # configs/ppo.yml's plane recipe
    python3 scripts/ship_plane_policy.py --run DIR             # ship that run's final policy
    python3 scripts/ship_plane_policy.py                       # re-record the shipped one

``--run``: copies the run folder's ``model.zip``, ``normalization.json`` and ``metadata.json``.
Both: evaluates the folder as a user loads it (agents.rl.artefacts.policy_files, no pickle) on the
100 fixed targets and on 1,000 others (agents.rl.evaluation.evaluate), stores the summary in the
metadata and every episode in ``episodes.json``, with the files' sha256 and how it was produced.
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
from agents.rl.artefacts.policy_files import load_policy  # noqa: E402
from agents.rl.artefacts.shipped import provenance, shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import (  # noqa: E402
    PLANE_TARGET_SEED,
    figures,
    fixed_targets,
    plane_record,
    rollout,
)

ENV_ID = "MicroConveyor2D-v0"
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", default=None,
                   help="a `microconveyor train --env MicroConveyor2D-v0` run folder to ship")
    args = p.parse_args()
    folder = shipped_path("ppo", ENV_ID)
    if args.run:
        ship(Path(args.run), folder)
    summary = record(folder)
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
