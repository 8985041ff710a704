"""Re-record the shipped policies' evaluations: summaries in each ``metadata.json``, every
episode in ``episodes.json`` beside it, with how they were produced.

Run from the repository root after a change that moves the dynamics (the tests compare a fresh
evaluation with these records within tolerances derived in tests/test_shipped_policies.py)::

    python scripts/record_shipped_evaluations.py [ENV_ID/NAME ...]   (default: all shipped)
    python scripts/record_shipped_evaluations.py --ship RUN ENV_ID/NAME   # ship a training run

``--ship``: copies the run folder's ``model.zip``, ``normalization.json`` and ``metadata.json``
(loaded first as a user loads them: data only, hashes verified) into
``agents/policies/ENV_ID/NAME`` and records its evaluations (:data:`NEW_RECORDS`).

Also records the sha256 of ``model.zip`` and ``normalization.json`` in the metadata (the loader
refuses a folder whose files do not match) and the folder format.
"""
from __future__ import annotations

import json
import sys


from agents.rl.artefacts.checkpoint import MODEL, NORMALIZATION, sha256
from agents.rl.artefacts.policy_files import PLANE_ENV_IDS, policy_scene
from agents.rl.evaluation.evaluate import fixed_targets, load_policy, rollout, summarize
from agents.rl.artefacts.shipped import provenance, shipped_path

# policy name -> {evaluation key: which env config ("nominal": the trained scene without
# randomisation, "trained": with the run's randomisation)}
EVALUATIONS = {"ppo": {"evaluation": "nominal", "evaluation_fresh": "nominal"},
               "ppo_refined": {"evaluation": "nominal", "evaluation_fresh": "nominal"},
               "ppo_randomised": {"evaluation": "trained", "evaluation_nominal": "nominal"}}
# what a newly shipped policy records: key -> (targets, target seed, env config); seed 12345
# is the set training monitors, seed 1 a held-out one
NEW_RECORDS = {"evaluation": (100, 12345, "trained"),
               "evaluation_nominal": (100, 12345, "nominal"),
               "evaluation_fresh": (1000, 1, "trained")}
# a policy not in EVALUATIONS re-records the NEW_RECORDS its metadata holds
EPISODES = "episodes.json"


def record(env_id: str, name: str) -> None:
    folder = shipped_path(name, env_id)
    meta_path = folder / "metadata.json"
    meta = json.loads(meta_path.read_text())
    meta.pop("files", None)                      # re-hashed below
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    pol = load_policy(folder)
    episodes = {}
    plan = EVALUATIONS.get(name) or {k: v[2] for k, v in NEW_RECORDS.items() if k in meta}
    for key, which in plan.items():
        old = meta[key]
        # "trained": the scene and randomisation it was trained under; "nominal": randomisation off
        cfg = policy_scene(meta) if which == "trained" else pol.config
        targets = fixed_targets(cfg, old["n_targets"], old["seed"])
        res = rollout(pol, targets, cfg, seed=old["seed"])
        summary = summarize(res, cfg.tolerance)
        summary.update(seed=old["seed"], target_range_m=list(cfg.target_range), config=which)
        meta[key] = {**{k: v for k, v in old.items() if k in ("steps", "wall_time_s")}, **summary}
        episodes[key] = {"config": which, "seed": old["seed"],
                         "target_m": res["targets_m"].tolist(), "error_m": res["error_m"].tolist(),
                         "outcome": res["outcome"].tolist(), "firings": res["firings"].tolist()}
        print(f"{env_id}/{name} {key}: success {summary['success_rate_50um']:.3f}, median "
              f"{summary['median_abs_error_m'] * 1e6:.4f} um", file=sys.stderr)
    meta["format"] = 2
    meta["evaluation_provenance"] = provenance()
    meta["files"] = {n: sha256(folder / n) for n in (MODEL, NORMALIZATION)}
    (folder / EPISODES).write_text(json.dumps(episodes, indent=0) + "\n")
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")


def ship(run: str, env_id: str, name: str) -> None:
    """Copy the policy of the training run folder ``run`` to ``agents/policies/env_id/name``,
    with the records to make (:data:`NEW_RECORDS`) named in its metadata."""
    import shutil
    from pathlib import Path

    from agents.rl.artefacts.checkpoint import META

    pol = load_policy(run)   # a complete, consistent policy folder, loaded as data
    if pol.metadata.get("env_id") != env_id:
        raise SystemExit(f"{run} holds a policy of {pol.metadata.get('env_id')!r}, not {env_id}")
    folder = shipped_path(name, env_id)
    folder.mkdir(parents=True, exist_ok=True)
    for f in (MODEL, NORMALIZATION, META):
        shutil.copyfile(Path(run) / f, folder / f)
    meta = json.loads((folder / META).read_text())
    randomised = getattr(policy_scene(meta), "randomised", False)
    for key, (n, seed, _) in NEW_RECORDS.items():
        if key == "evaluation_nominal" and not randomised:
            continue   # trained on the nominal scene: "evaluation" is that one
        meta[key] = {"n_targets": n, "seed": seed}
    (folder / META).write_text(json.dumps(meta, indent=2) + "\n")


if __name__ == "__main__":
    from agents.rl.artefacts.shipped import shipped_policies

    if sys.argv[1:2] == ["--ship"]:
        run, item = sys.argv[2], sys.argv[3]
        ship(run, *item.split("/"))
        record(*item.split("/"))
        raise SystemExit(0)
    wanted = sys.argv[1:] or [f"{e}/{n}" for e, names in shipped_policies().items()
                              for n in names]
    for item in wanted:
        env_id, _, name = item.partition("/")
        if env_id in PLANE_ENV_IDS:   # the plane's record: scripts/ship_plane_policy.py
            from ship_plane_policy import record as record_plane

            print(f"{item}: {record_plane(shipped_path(name, env_id))}", file=sys.stderr)
            continue
        record(env_id, name)
