"""Re-record the shipped policies' evaluations: summaries in each ``metadata.json``, every
episode in ``episodes.json`` beside it, with how they were produced.

Run from the repository root after a change that moves the dynamics (the tests compare a fresh
evaluation with these records within tolerances derived in tests/test_shipped_policies.py)::

    python scripts/record_shipped_evaluations.py [ENV_ID/NAME ...]   (default: all shipped)
    python scripts/record_shipped_evaluations.py --ship RUN ENV_ID/NAME   # ship a training run

``--ship``: copies the run folder's ``model.zip``, ``normalization.json`` and ``metadata.json``
(loaded first as a user loads them: data only, hashes verified) into
``agents/policies/ENV_ID/NAME`` (staged and loaded there before it replaces anything) and
records its evaluations (:data:`NEW_RECORDS`).

A folder is loaded as a user loads it before anything in it changes (one that does not load is
refused untouched); the records and the metadata, with the sha256 of the files the loader reads
(``files``: without them it refuses the folder) and the folder format, are written whole and the
folder loaded again.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))   # ship_plane_policy beside it

from agents.rl.artefacts.policy_files import PLANE_ENV_IDS, policy_scene  # noqa: E402
from agents.rl.evaluation.evaluate import fixed_targets, rollout, summarize  # noqa: E402
from agents.rl.artefacts.shipped import provenance, shipped_path  # noqa: E402
from microconveyor_env.envs import EnvConfig  # noqa: E402
from ship_plane_policy import loaded_metadata, place_policy, write_records  # noqa: E402

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
    """Re-record the evaluations of the shipped ``env_id/name``: the folder is loaded as a user
    loads it (a folder that does not load is refused untouched), and its records and metadata
    (``files`` recomputed) are written whole (``ship_plane_policy.write_records``)."""
    folder = shipped_path(name, env_id)
    pol, meta = loaded_metadata(folder)
    episodes = {}
    plan = EVALUATIONS.get(name) or {k: v[2] for k, v in NEW_RECORDS.items() if k in meta}
    for key, which in plan.items():
        old = meta[key]
        # "trained": the scene and randomisation it was trained under; "nominal": randomisation off
        cfg = policy_scene(meta) if which == "trained" else pol.config
        assert isinstance(cfg, EnvConfig), f"{folder} holds no policy of the line"
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
    write_records(folder, pol, meta, episodes)


def ship(run: str, env_id: str, name: str) -> None:
    """Copy the policy of the training run folder ``run`` to ``agents/policies/env_id/name``,
    with the records to make (:data:`NEW_RECORDS`) named in its metadata. The run is loaded
    first (a complete, consistent policy folder, loaded as data); the new folder is staged and
    loaded before it replaces anything (``ship_plane_policy.place_policy``)."""
    pol, meta = loaded_metadata(Path(run))
    if meta.get("env_id") != env_id:
        raise SystemExit(f"{run} holds a policy of {meta.get('env_id')!r}, not {env_id}")
    randomised = getattr(policy_scene(meta), "randomised", False)
    for key, (n, seed, _) in NEW_RECORDS.items():
        if key == "evaluation_nominal" and not randomised:
            continue   # trained on the nominal scene: "evaluation" is that one
        meta[key] = {"n_targets": n, "seed": seed}
    place_policy(Path(run), meta, pol.metadata["files"], shipped_path(name, env_id))


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
            from ship_plane_policy import ENV_ID as PLANE_ID, record as record_plane, \
                record_randomised

            plane = record_plane if env_id == PLANE_ID else record_randomised
            print(f"{item}: {plane(shipped_path(name, env_id))}", file=sys.stderr)
            continue
        record(env_id, name)
