"""Wall time of one `microconveyor imitate` training on one core, per seed, and whether the policy
it writes is at the bar on held-out targets.

    python benchmarks/imitate_wall_time.py --seeds 0-9 --out runs/imitate-bench \\
        --json docs/figures/imitate_v1_seeds.json [--env MicroConveyor-v1] [--cpu 0]

Each seed runs ``microconveyor imitate --env ENV --seed S --out OUT/s<S>`` as its own process,
pinned to one CPU (``--cpu``; its torch and numba threads set to 1), one seed after the other:
the wall time is the command's, from start to the written policy folder, imports and compilation
included (the numba cache warm, as after an install's first run). Its CPU time (user + system,
from the OS) is recorded beside it. Then each policy is evaluated on ``--targets`` held-out
targets (``--eval-seed`` 1: not the set training monitors; the evaluation is not timed in the
wall time) and checked against the bar: at least ``--bar-success`` at rest within the env's
tolerance and a median |error| at most ``--bar-median-m``.

Writes JSON (SI units): per seed the wall and CPU time [s], success, median and 90th percentile
|error| [m], detachment rate, whether it is at the bar; over the seeds the IQM of the success
with its 95 % bootstrap interval, the worst seed, the median and slowest wall time; the machine,
its load average before and after, the date and the command. Not a test: timings are noisy;
record what else ran (``--note``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from agents.rl.evaluation.evaluate import evaluate, load_policy  # noqa: E402
from agents.rl.evaluation.seeds import iqm_interval  # noqa: E402


def seed_list(text: str) -> list[int]:
    """``0-9`` or ``0,3,5`` (or both: ``0-4,7``)."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def train(env_id: str, seed: int, folder: Path, cpu: int | None, log: Path) -> dict:
    """Run the command once; its wall and CPU time [s]."""
    cmd = [sys.executable, "-m", "microconveyor_env.cli", "imitate", "--env", env_id,
           "--seed", str(seed), "--out", str(folder)]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1"}

    def pin() -> None:
        if cpu is not None:
            os.sched_setaffinity(0, {cpu})

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    with open(log, "w") as out:
        subprocess.run(cmd, check=True, stdout=out, stderr=subprocess.STDOUT, env=env,
                       preexec_fn=pin)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_time_s": wall, "cpu_time_s": cpu_s, "command": " ".join(cmd[1:])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="MicroConveyor-v1")
    ap.add_argument("--seeds", type=seed_list, default=seed_list("0-9"))
    ap.add_argument("--out", type=Path, default=Path("runs/imitate-bench"))
    ap.add_argument("--json", type=Path, default=None, help="write the JSON here too")
    ap.add_argument("--cpu", type=int, default=0, help="the CPU each training is pinned to "
                                                       "(-1: not pinned)")
    ap.add_argument("--targets", type=int, default=1000)
    ap.add_argument("--eval-seed", type=int, default=1)
    ap.add_argument("--bar-success", type=float, default=0.90)
    ap.add_argument("--bar-median-m", type=float, default=20e-6)
    ap.add_argument("--note", default="", help="what else ran on the machine")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cpu = None if args.cpu < 0 else args.cpu
    load_before = os.getloadavg()
    rows = []
    for seed in args.seeds:
        folder = args.out / f"s{seed}"
        timing = train(args.env, seed, folder, cpu, args.out / f"s{seed}.log")
        pol = load_policy(folder)
        r = evaluate(pol, n_targets=args.targets, seed=args.eval_seed)
        row = {"seed": seed, **timing, "success_rate": r["success_rate"],
               "median_abs_error_m": r["median_abs_error_m"],
               "p90_abs_error_m": r["p90_abs_error_m"], "detach_rate": r["detach_rate"],
               "at_bar": bool(r["success_rate"] >= args.bar_success
                              and r["median_abs_error_m"] <= args.bar_median_m)}
        rows.append(row)
        print(f"seed {seed}: {timing['wall_time_s']:.0f} s wall, {timing['cpu_time_s']:.0f} s "
              f"CPU; {row['success_rate']:.1%} within the tolerance, median "
              f"{row['median_abs_error_m'] * 1e6:.1f} µm{'' if row['at_bar'] else ' (below the bar)'}",
              flush=True)
    success = np.array([r["success_rate"] for r in rows])
    walls = np.array([r["wall_time_s"] for r in rows])
    worst = rows[int(np.argmin(success))]
    meta = json.loads((args.out / f"s{args.seeds[0]}" / "metadata.json").read_text())
    out = {
        "env_id": args.env, "what": "wall time of one `microconveyor imitate` training on one "
                                    "core, and its policy on held-out targets",
        "recipe": meta.get("hyperparams"), "expert": meta.get("expert"),
        "targets": args.targets, "eval_seed": args.eval_seed,
        "bar": {"success_rate": args.bar_success, "median_abs_error_m": args.bar_median_m},
        "seeds": rows,
        "summary": {"seeds": len(rows), "at_bar": int(sum(r["at_bar"] for r in rows)),
                    "success_iqm": iqm_interval(success),
                    "worst_seed": {k: worst[k] for k in ("seed", "success_rate",
                                                         "median_abs_error_m")},
                    "median_wall_time_s": float(np.median(walls)),
                    "slowest_wall_time_s": float(walls.max()),
                    "slowest_seed": int(rows[int(np.argmax(walls))]["seed"]),
                    "median_cpu_time_s": float(np.median([r["cpu_time_s"] for r in rows]))},
        "machine": {"cpu_count": os.cpu_count(), "processor": platform.processor(),
                    "pinned_cpu": cpu, "load_average_before": load_before,
                    "load_average_after": os.getloadavg(),
                    "aten_cpu_capability": os.environ.get("ATEN_CPU_CAPABILITY", "default")},
        "note": args.note,
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "command": "python benchmarks/imitate_wall_time.py " + " ".join(sys.argv[1:]),
    }
    text = json.dumps(out, indent=1) + "\n"
    (args.out / "imitate_wall_time.json").write_text(text)
    if args.json:
        args.json.write_text(text)
    s = out["summary"]
    print(f"{s['at_bar']}/{s['seeds']} seeds at the bar; success IQM "
          f"{s['success_iqm']['iqm']:.1%} [{s['success_iqm']['ci95'][0]:.1%}, "
          f"{s['success_iqm']['ci95'][1]:.1%}]; worst seed {worst['seed']} "
          f"{worst['success_rate']:.1%}; wall time median {s['median_wall_time_s']:.0f} s, "
          f"slowest {s['slowest_wall_time_s']:.0f} s (seed {s['slowest_seed']})")


if __name__ == "__main__":
    main()
