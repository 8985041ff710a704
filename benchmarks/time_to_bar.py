"""Time to the bar on MicroConveyor-v1: wall time and env steps until the fixed-target success
(±50 µm, 100 targets, the evaluation `microconveyor train` runs) first reaches 50 % and 90 %,
for each method at an equal wall budget, over several seeds.

    python benchmarks/time_to_bar.py --minutes 5 --seeds 0 1 2 --jobs 1 --out runs/ttb
    python benchmarks/time_to_bar.py --aggregate-only --out runs/ttb   # tables from finished runs

Each (method, seed) trains from scratch with `microconveyor train --max-minutes MINUTES` into
OUT/<method>_s<seed>. With ``--jobs 2`` two trainings share the 2 cores: their wall times are
then those of a loaded machine (the JSON records ``jobs``); compare methods within one run of
this script. Writes OUT/time_to_bar.json and OUT/time_to_bar.png (success against wall time and
against steps). Not a test: timings here are noisy.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

# method -> (train arguments, steps between evaluations)
METHODS: dict[str, tuple[list[str], int]] = {
    "ppo": (["--algo", "ppo", "--env", "MicroConveyor-v1"], 250_000),
    "sac_her": (["--algo", "sac", "--env", "MicroConveyorGoal-v1"], 10_000),
    "tqc_her": (["--algo", "tqc", "--env", "MicroConveyorGoal-v1"], 10_000),
}
BARS = (0.5, 0.9)


def run_one(method: str, seed: int, minutes: float, out: Path, targets: int) -> Path:
    args, eval_freq = METHODS[method]
    folder = out / f"{method}_s{seed}"
    if (folder / "metadata.json").is_file():
        return folder  # finished earlier
    cmd = [sys.executable, "-m", "microconveyor_env.cli", "train", *args, "--seed", str(seed),
           "--out", str(folder), "--max-minutes", str(minutes), "--steps", str(10**9),
           "--eval-freq", str(eval_freq), "--eval-targets", str(targets),
           "--checkpoint-freq", str(10**9), "--no-progress"]
    t = time.perf_counter()
    with open(out / f"{method}_s{seed}.log", "w") as log:
        subprocess.run(cmd, check=True, stdout=log, stderr=subprocess.STDOUT)
    print(f"{method} seed {seed}: {time.perf_counter() - t:.0f} s", file=sys.stderr, flush=True)
    return folder


def first_pass(evals: list[dict], bar: float) -> dict | None:
    for e in evals:
        if e["success_rate_50um"] >= bar:
            return {"steps": int(e["steps"]), "wall_time_s": float(e["wall_time_s"])}
    return None


def summarize(folder: Path) -> dict:
    evals = [json.loads(line) for line in (folder / "evaluations.jsonl").read_text().splitlines()
             if line.strip()]
    meta = json.loads((folder / "metadata.json").read_text())
    out = {"run": str(folder), "algo": meta.get("algo"), "env_id": meta.get("env_id"),
           "seed": meta.get("seed"), "steps": meta.get("steps"),
           "wall_time_s": meta.get("wall_time_s"),
           "final_success_rate_50um": evals[-1]["success_rate_50um"] if evals else None,
           "final_median_abs_error_m": evals[-1]["median_abs_error_m"] if evals else None,
           "curve": {k: [e[k] for e in evals] for k in ("steps", "wall_time_s",
                                                        "success_rate_50um")}}
    for bar in BARS:
        out[f"first_{round(bar * 100)}pct"] = first_pass(evals, bar)
    return out


def table(rows: list[dict]) -> str:
    lines = ["| method | seed | 50 %: wall [s] / steps | 90 %: wall [s] / steps | final ±50 µm | "
             "final median [µm] |", "|---|---|---|---|---|---|"]

    def cell(hit: dict | None) -> str:
        return "not reached" if hit is None else f"{hit['wall_time_s']:.0f} / {hit['steps']:,}"

    for r in rows:
        med = r["final_median_abs_error_m"]
        lines.append(f"| {r['method']} | {r['seed']} | {cell(r['first_50pct'])} | "
                     f"{cell(r['first_90pct'])} | {100 * (r['final_success_rate_50um'] or 0):.0f} % | "
                     f"{'-' if med is None else f'{med * 1e6:.1f}'} |")
    return "\n".join(lines)


def plot(rows: list[dict], path: Path, minutes: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    colours = {m: f"C{i}" for i, m in enumerate(METHODS)}
    for r in rows:
        c = r["curve"]
        for ax, key, scale in ((axes[0], "wall_time_s", 1 / 60), (axes[1], "steps", 1e-6)):
            # the steps axis is logarithmic: an evaluation at step 0 (none is made) would vanish
            pts = [(v * scale, 100 * s) for v, s in zip(c[key], c["success_rate_50um"], strict=True)
                   if key != "steps" or v > 0]
            ax.plot([x for x, _ in pts], [y for _, y in pts], color=colours[r["method"]],
                    alpha=0.8,
                    label=r["method"] if r["seed"] == rows[0]["seed"] or key == "steps" else None)
    for ax, xl in ((axes[0], "wall time [min]"), (axes[1], "env steps [millions]")):
        for bar in BARS:
            ax.axhline(100 * bar, color="grey", ls=":", lw=1)
            ax.annotate(f"{100 * bar:.0f} % bar", (0.01, 100 * bar + 1),
                        xycoords=("axes fraction", "data"), color="grey", fontsize=8)
        ax.set_xlabel(xl)
        ax.set_ylabel("success within ±50 µm [%] (100 fixed targets)")
        ax.set_ylim(0, 100)
        ax.grid(alpha=0.3)
    axes[1].set_xscale("log")  # off-policy runs take ~10^5 steps, PPO ~10^6 in the same time
    handles, labels = axes[0].get_legend_handles_labels()
    uniq = dict(zip(labels, handles, strict=True))
    axes[0].legend(uniq.values(), uniq.keys(), loc="upper left", bbox_to_anchor=(0.0, 0.87))
    axes[0].axvline(minutes, color="k", lw=0.8)
    fig.suptitle(f"MicroConveyor-v1: time to the bar, {minutes:g}-min budget per run, one line "
                 "per seed")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", nargs="+", choices=list(METHODS), default=["ppo", "sac_her"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--minutes", type=float, default=5.0, help="wall budget per run [min]")
    ap.add_argument("--jobs", type=int, default=1, help="trainings at once (2: a loaded machine)")
    ap.add_argument("--targets", type=int, default=100, help="targets per evaluation")
    ap.add_argument("--out", type=Path, default=Path("runs/time_to_bar"))
    ap.add_argument("--aggregate-only", action="store_true", help="only read finished runs")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    jobs = [(m, s) for m in a.methods for s in a.seeds]
    if not a.aggregate_only:
        with ThreadPoolExecutor(a.jobs) as pool:
            list(pool.map(lambda ms: run_one(ms[0], ms[1], a.minutes, a.out, a.targets), jobs))
    rows = []
    for m, s in jobs:
        folder = a.out / f"{m}_s{s}"
        if (folder / "metadata.json").is_file():
            rows.append({"method": m, **summarize(folder)})
    res = {"minutes": a.minutes, "jobs": a.jobs, "targets": a.targets, "rows": rows}
    (a.out / "time_to_bar.json").write_text(json.dumps(res, indent=1))
    plot(rows, a.out / "time_to_bar.png", a.minutes)
    print(table(rows))
    print(f"wrote {a.out / 'time_to_bar.json'} and {a.out / 'time_to_bar.png'}")


if __name__ == "__main__":
    main()
