"""The plane's figure (docs/results.md, "Positioning in the plane"): final Euclidean error of the shipped PPO of
MicroConveyor2D-v0 and of differential evolution per target (open loop) on the same 100 targets.

    python3 scripts/plane_figures.py [--de DIR]
    python3 scripts/plane_figures.py --firings

``--firings`` (MicroConveyor2D-v1's episode length, docs/env.md): the shipped MicroConveyor2D-v0
PPO played under v1's per-episode randomisation with 8, 10, 12 and 16 firings on 1,000 targets
for each of two seeds (targets and episode draws), and without randomisation with 8; writes
docs/figures/plane_v1_firings.json.

Writes docs/figures/plane_v0_errors.png (ECDF of the final error, um on a log axis, the +-50 um
success radius marked) and docs/figures/plane_v0_errors.json (every error plotted, the summaries
and where they came from). The PPO's errors are its recorded evaluation
(agents/policies/MicroConveyor2D-v0/ppo/episodes.json). DE's come from ``DIR/de{2000,10000,20000}
.json`` (one JSON per budget: ``{"wall_s": ..., "rows": [{"target_m": ..., "error_m": ...}, ...]}``) when ``--de`` is
given, and otherwise from the JSON written before, which keeps them (DE's runs take minutes per
budget).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from agents.rl.evaluation.evaluate import PLANE_TARGET_SEED, fixed_targets
from agents.rl.artefacts.shipped import shipped_path
from microconveyor_env.envs.plane.config import PlaneEnvConfig

OUT = ROOT / "docs" / "figures" / "plane_v0_errors"
BUDGETS = (2000, 10000, 20000)
TOL = 50e-6  # [m] the env's success radius
XMIN_UM = 1e-2  # [um] left edge of the axis; the curves start there at the fraction below it
DE_NOTE = ("DE: agents/openloop/search.py minimize('de') per target over the episode's 8 x 5 "
           "actions played open loop on the deterministic nominal model, "
           "seed = target index; error_m is the best plan's Euclidean error at rest [m]. "
           "wall_s measured on the shared 2-core machine under load (2,000 episodes ran under "
           "heavier load than 10,000), one core.")


def de_from_runs(run: Path, targets: np.ndarray) -> dict:
    out = {}
    for b in BUDGETS:
        d = json.loads((run / f"de{b}.json").read_text())
        tg = np.array([r["target_m"] for r in d["rows"]])
        if tg.shape != targets.shape or not np.array_equal(tg, targets):
            raise SystemExit(f"{run / f'de{b}.json'}: its targets are not the 100 fixed targets")
        out[str(b)] = {"episodes_per_target": b, "wall_s": d["wall_s"],
                       "error_m": [r["error_m"] for r in d["rows"]]}
    return out


def summary(err: np.ndarray) -> dict:
    return {"success_rate_50um": float(np.mean(err <= TOL)),
            "median_error_m": float(np.median(err)),
            "p90_error_m": float(np.percentile(err, 90))}


FIRINGS_OUT = ROOT / "docs" / "figures" / "plane_v1_firings.json"
FIRINGS = ((8, 1.0), (10, 1.5), (12, 1.0), (12, 1.5), (16, 2.0))   # (max_firings, max_time [s])
FIRINGS_SEEDS = (11, 12)
FIRINGS_TARGETS = 1000


def firings_scan(out: Path = FIRINGS_OUT, n_targets: int = FIRINGS_TARGETS) -> dict:
    """The shipped v0 PPO under v1's randomisation with more firings (module docstring), on
    ``n_targets`` targets per seed; written to ``out``."""
    from agents.rl.artefacts.policy_files import load_policy
    from agents.rl.evaluation.evaluate import figures, rollout
    from microconveyor_env.envs.core.versions import scene_config

    pol = load_policy(shipped_path("ppo", "MicroConveyor2D-v0"))
    off = {"action_noise": 0.0, "friction_factor_range": (1.0, 1.0),
           "mass_factor_range": (1.0, 1.0)}
    rows = []
    cases = [(n, t, "v1") for n, t in FIRINGS] + [(8, 1.0, "nominal")]
    for n, t, level in cases:
        cfg = scene_config("MicroConveyor2D-v1", num_threads=1, max_firings=n, max_time=t,
                           **(off if level == "nominal" else {}))
        for seed in FIRINGS_SEEDS:
            f = figures(rollout(pol, fixed_targets(cfg, n_targets, seed), cfg, seed=seed), TOL)
            rows.append({"max_firings": n, "max_time_s": t, "randomisation": level,
                         "action_noise": cfg.action_noise,
                         "friction_factor_range": list(cfg.friction_factor_range),
                         "mass_factor_range": list(cfg.mass_factor_range), "seed": seed,
                         "n_targets": n_targets,
                         **{k: f[k] for k in ("success_rate_50um", "success_rate_100um",
                                              "median_abs_error_m", "rest_rate", "detach_rate",
                                              "mean_firings")}})
    data = {"policy": "agents/policies/MicroConveyor2D-v0/ppo (trained with 8 firings, no "
                      "randomisation)",
            "env_id": "MicroConveyor2D-v1", "tolerance_m": TOL, "rows": rows,
            "command": "python3 scripts/plane_figures.py --firings"}
    out.write_text(json.dumps(data, indent=1) + "\n")
    return data


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--de", default=None, help="folder of DE runs' de<budget>.json (default: the stored JSON's)")
    p.add_argument("--firings", action="store_true",
                   help="MicroConveyor2D-v1's firing count scan only (docs/figures/plane_v1_firings.json)")
    p.add_argument("--out", type=Path, default=None,
                   help="where to write: the chart's stem (STEM.png, STEM.json; default "
                        "docs/figures/plane_v0_errors), with --firings the JSON (default "
                        "docs/figures/plane_v1_firings.json); DE's rows are read from the "
                        "stored JSON unless --de")
    p.add_argument("--targets", type=int, default=FIRINGS_TARGETS,
                   help=f"with --firings: targets per seed (default {FIRINGS_TARGETS})")
    args = p.parse_args()
    if args.firings:
        for r in firings_scan(args.out or FIRINGS_OUT, args.targets)["rows"]:
            print(r["max_firings"], r["max_time_s"], r["randomisation"], r["seed"],
                  f"{r['success_rate_50um']:.3f}", f"{r['mean_firings']:.2f}")
        return
    folder = shipped_path("ppo", "MicroConveyor2D-v0")
    meta = json.loads((folder / "metadata.json").read_text())
    rec = json.loads((folder / "episodes.json").read_text())["evaluation"]
    targets = fixed_targets(PlaneEnvConfig.from_yaml(), 100, PLANE_TARGET_SEED)
    if not np.array_equal(np.array(rec["target_m"]), targets):
        raise SystemExit("the shipped policy's record is not on the 100 fixed targets")
    if args.de:
        de = de_from_runs(Path(args.de), targets)
    else:
        de = json.loads(OUT.with_suffix(".json").read_text())["de"]
    if any(o != "rest" for o in rec["outcome"]):
        raise SystemExit("a PPO episode did not end at rest: the ECDF of errors would hide it")
    ppo_err = np.array(rec["error_m"])
    data: dict[str, Any] = {"targets": {"n": 100, "seed": PLANE_TARGET_SEED, "box_m": meta["evaluation"]
                        ["target_box_m"], "target_m": targets.tolist()},
            "tolerance_m": TOL,
            "ppo": {"policy": "agents/policies/MicroConveyor2D-v0/ppo", "seed": meta["seed"],
                    "steps": meta["steps"], "train_wall_s": meta["wall_time_s"],
                    "mean_firings": meta["evaluation"]["mean_firings"],
                    "error_m": ppo_err.tolist(), **summary(ppo_err)},
            "de": {k: {**v, **summary(np.array(v["error_m"], float))} for k, v in de.items()},
            "de_note": DE_NOTE,
            "command": "python3 scripts/plane_figures.py"}
    out = args.out or OUT
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(data, indent=1) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    curves = [(f"PPO (shipped; {data['ppo']['mean_firings']:.1f} forward passes per target)",
               ppo_err, "C0", "-")]
    for k, col in zip(sorted(de, key=int), ("C1", "C2", "C3"), strict=True):
        curves.append((f"DE open loop, {int(k):,} episodes per target",
                       np.array(de[k]["error_m"], float), col, "--"))
    for label, err, col, ls in curves:
        x = np.sort(err) * 1e6
        y = np.arange(1, len(x) + 1) / len(x)
        s = summary(err)
        ax.step(x, y, where="post", color=col, ls=ls,
                label=f"{label}: {s['success_rate_50um']:.0%}, median "
                      f"{s['median_error_m'] * 1e6:.1f} µm")
    ax.axvline(TOL * 1e6, color="k", lw=0.8, ls=":")
    ax.text(TOL * 1e6 * 1.08, 0.04, "±50 µm (success)", fontsize=8)
    ax.set_xscale("log")
    ax.set_xlim(XMIN_UM, None)   # DE's best plans reach 1e-7 um: below XMIN_UM, at the axis edge
    ax.set_xlabel(f"final Euclidean error from the target [µm] (below {XMIN_UM:g} µm: at the "
                  "left edge)")
    ax.set_ylabel("fraction of the 100 targets")
    ax.set_ylim(0, 1.02)
    ax.set_title("MicroConveyor2D-v0: 100 fixed targets", fontsize=10)
    ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=120)
    print(json.dumps({"ppo": summary(ppo_err),
                      **{f"de{k}": summary(np.array(v["error_m"], float))
                         for k, v in de.items()}}))


if __name__ == "__main__":
    main()
