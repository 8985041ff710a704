"""Wall time of one `microconveyor imitate` training on one core, per seed, and whether the policy
it writes meets the criterion on held-out targets.

    python benchmarks/imitate_wall_time.py --seeds 0-9 --out runs/imitate-bench \\
        --json docs/figures/imitate_v1_seeds.json [--env MicroConveyor-v1] [--cpu 0]
    ATEN_CPU_CAPABILITY=default MKL_CBWR=COMPATIBLE OPENBLAS_CORETYPE=Prescott \\
        python benchmarks/imitate_wall_time.py --seeds 0-2 --out runs/imitate-scalar \\
        --compare-with runs/imitate-bench --json docs/figures/imitate_v1_code_paths.json

Each seed runs ``microconveyor imitate --env ENV --seed S --out OUT/s<S>`` as its own process,
pinned to one CPU (``--cpu``; its torch and numba threads set to 1), one seed after the other
(``--parallel-cpus 0,1``: side by side, one per CPU, each pinned to its own):
the wall time is the command's, from start to the written policy folder, imports and compilation
included (the numba cache warm, as after an install's first run). Its CPU time (user + system,
from the OS) is recorded beside it. Then each policy is evaluated on ``--targets`` held-out
targets (``--eval-seed`` 1: not the set training monitors; the evaluation is not timed in the
wall time) and checked against the criterion: at least ``--min-success`` at rest within the env's
tolerance and a median |error| at most ``--max-median-m``.

``--compare-with DIR``: the same seeds trained on another of torch's CPU code paths (the second
command above: torch's kernels without SIMD and the BLAS on its baseline path, against the
machine's default, AVX2 here) are evaluated on the same targets too, and each row says whether
the two policies played every episode identically and whether both are on the same side of
the criterion.

The first seed's policy is also timed acting on one observation at a time (``act_time_s``).

Writes JSON (SI units): per seed the wall and CPU time [s], success, median and 90th percentile
|error| [m], detachment rate, whether it meets the criterion; over the seeds the IQM of the success
with its 95 % bootstrap interval, the worst seed, the median and slowest wall time; the machine,
its load average before and after, the date and the command. Not a test: timings are noisy;
record what else ran (``--note``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from datetime import datetime, UTC
from pathlib import Path

import numpy as np


from agents.rl.evaluation.evaluate import (figures, fixed_targets, load_policy,
                                            rollout)
from agents.rl.evaluation.seeds import iqm_interval


def seed_list(text: str) -> list[int]:
    """``0-9`` or ``0,3,5`` (or both: ``0-4,7``)."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def train(env_id: str, seed: int, folder: Path, cpu: int | None, log: Path,
          extra: tuple[str, ...] = ()) -> dict:
    """Run the command once (``extra``: further options of ``imitate``); its wall and CPU time
    [s]."""
    cmd = [sys.executable, "-m", "microconveyor_env.cli", "imitate", "--env", env_id,
           "--seed", str(seed), "--out", str(folder), *extra]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1"}

    def pin() -> None:
        if cpu is not None:
            os.sched_setaffinity(0, {cpu})

    t = time.perf_counter()
    with open(log, "w") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env,
                                preexec_fn=pin)
        _, status, usage = os.wait4(proc.pid, 0)   # this child's own CPU time
        proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t
    if proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, cmd)
    cpu_s = usage.ru_utime + usage.ru_stime
    return {"wall_time_s": wall, "cpu_time_s": cpu_s, "command": " ".join(cmd[1:])}


def torch_capability() -> str:
    """The SIMD level torch's own kernels run at in this process (``ATEN_CPU_CAPABILITY`` caps
    it); the trainings inherit the environment."""
    import torch

    return str(torch.backends.cpu.get_cpu_capability())


def held_out(folder: Path, n: int, seed: int) -> tuple[dict, np.ndarray]:
    """The policy in ``folder`` on ``n`` held-out targets drawn with ``seed``: its figures and
    every episode's signed error [m]."""
    pol = load_policy(folder)
    cfg = pol.config
    if cfg is None:
        raise SystemExit(f"{folder}: its policy names no env")
    res = rollout(pol, fixed_targets(cfg, n, seed), cfg, seed=seed)
    return figures(res, cfg.tolerance), np.asarray(res["error_m"], float)


def act_time(folder: Path, calls: int = 2000) -> float:
    """Seconds per action of the policy in ``folder`` for one observation at a time (as a
    controller calls it), the mean over ``calls`` calls after one warm-up call."""
    from microconveyor_env.envs.core.versions import vector_class_of

    pol = load_policy(folder)
    obs, _ = vector_class_of(pol.config)(1, config=pol.config).reset(seed=0)   # a first state
    pol.act(obs)
    t = time.perf_counter()
    for _ in range(calls):
        pol.act(obs)
    return (time.perf_counter() - t) / calls


def criterion_row(r: dict, args: argparse.Namespace) -> dict:
    return {"success_rate": r["success_rate"], "median_abs_error_m": r["median_abs_error_m"],
            "p90_abs_error_m": r["p90_abs_error_m"], "detach_rate": r["detach_rate"],
            "meets_criterion": bool(r["success_rate"] >= args.min_success
                           and r["median_abs_error_m"] <= args.max_median_m)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="MicroConveyor-v1")
    ap.add_argument("--seeds", type=seed_list, default=seed_list("0-9"))
    ap.add_argument("--out", type=Path, default=Path("runs/imitate-bench"))
    ap.add_argument("--json", type=Path, default=None, help="write the JSON here too")
    ap.add_argument("--cpu", type=int, default=0, help="the CPU each training is pinned to "
                                                       "(-1: not pinned)")
    ap.add_argument("--parallel-cpus", type=seed_list, default=None, metavar="LIST",
                    help="train side by side instead, one training per CPU of LIST (e.g. 0,1), "
                         "each pinned to its CPU; the policies are evaluated afterwards")
    ap.add_argument("--targets", type=int, default=1000)
    ap.add_argument("--eval-seed", type=int, default=1)
    ap.add_argument("--min-success", type=float, default=0.90)
    ap.add_argument("--max-median-m", type=float, default=20e-6)
    ap.add_argument("--note", default="", help="what else ran on the machine")
    ap.add_argument("--imitate-args", type=shlex.split, default=[],
                    help="further options of each `microconveyor imitate` run, one string (e.g. "
                         "'--rounds 1 --episodes 2' for a quick check of this script)")
    ap.add_argument("--compare-with", type=Path, default=None,
                    help="a run folder of this script on another CPU code path (module docstring)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cpu = None if args.cpu < 0 else args.cpu
    load_before = os.getloadavg()
    rows = []
    timings: dict[int, dict] = {}
    if args.parallel_cpus:
        import queue
        from concurrent.futures import ThreadPoolExecutor

        free: queue.Queue = queue.Queue()
        for c in args.parallel_cpus:
            free.put(c)

        def side_by_side(seed: int) -> dict:
            c = free.get()
            try:
                return {**train(args.env, seed, args.out / f"s{seed}", c,
                                args.out / f"s{seed}.log", tuple(args.imitate_args)), "cpu": c}
            finally:
                free.put(c)

        with ThreadPoolExecutor(len(args.parallel_cpus)) as pool:
            timings = dict(zip(args.seeds, pool.map(side_by_side, args.seeds), strict=True))
    for seed in args.seeds:
        folder = args.out / f"s{seed}"
        timing = timings.get(seed) or train(args.env, seed, folder, cpu,
                                            args.out / f"s{seed}.log", tuple(args.imitate_args))
        r, errors = held_out(folder, args.targets, args.eval_seed)
        row = {"seed": seed, **timing, **criterion_row(r, args)}
        if args.compare_with is not None:
            other, other_errors = held_out(args.compare_with / f"s{seed}", args.targets,
                                           args.eval_seed)
            row["other_path"] = {"run": str(args.compare_with / f"s{seed}"),
                                 **criterion_row(other, args),
                                 "same_episodes": bool(np.array_equal(errors, other_errors)),
                                 "max_error_difference_m": float(np.max(np.abs(
                                     errors - other_errors)))}
            row["same_side_of_criterion"] = (row["meets_criterion"]
                                             == row["other_path"]["meets_criterion"])
        rows.append(row)
        print(f"seed {seed}: {timing['wall_time_s']:.0f} s wall, {timing['cpu_time_s']:.0f} s "
              f"CPU; {row['success_rate']:.1%} within the tolerance, median "
              f"{row['median_abs_error_m'] * 1e6:.1f} µm"
              f"{'' if row['meets_criterion'] else ' (below the criterion)'}",
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
        "criterion": {"success_rate": args.min_success, "median_abs_error_m": args.max_median_m},
        "seeds": rows,
        "summary": {"seeds": len(rows),
                    "meeting_criterion": int(sum(r["meets_criterion"] for r in rows)),
                    "success_iqm": iqm_interval(success),
                    "worst_seed": {k: worst[k] for k in ("seed", "success_rate",
                                                         "median_abs_error_m")},
                    "median_wall_time_s": float(np.median(walls)),
                    "slowest_wall_time_s": float(walls.max()),
                    "slowest_seed": int(rows[int(np.argmax(walls))]["seed"]),
                    "median_cpu_time_s": float(np.median([r["cpu_time_s"] for r in rows]))},
        "act_time_s": act_time(args.out / f"s{args.seeds[0]}"),
        "compared_with": None if args.compare_with is None else {
            "run": str(args.compare_with),
            "same_side_of_criterion": int(sum(r["same_side_of_criterion"] for r in rows)),
            "same_episodes": int(sum(r["other_path"]["same_episodes"] for r in rows))},
        "machine": {"cpu_count": os.cpu_count(), "processor": platform.processor(),
                    "pinned_cpu": cpu, "parallel_cpus": args.parallel_cpus,
                    "load_average_before": load_before,
                    "load_average_after": os.getloadavg(),
                    "torch_cpu_capability": torch_capability(),
                    "env": {k: os.environ[k] for k in ("ATEN_CPU_CAPABILITY", "MKL_CBWR",
                                                       "OPENBLAS_CORETYPE") if k in os.environ}},
        "note": args.note,
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "command": "python benchmarks/imitate_wall_time.py " + " ".join(sys.argv[1:]),
    }
    text = json.dumps(out, indent=1) + "\n"
    (args.out / "imitate_wall_time.json").write_text(text)
    if args.json:
        args.json.write_text(text)
    s = out["summary"]
    print(f"{s['meeting_criterion']}/{s['seeds']} seeds meet the criterion; success IQM "
          f"{s['success_iqm']['iqm']:.1%} [{s['success_iqm']['ci95'][0]:.1%}, "
          f"{s['success_iqm']['ci95'][1]:.1%}]; worst seed {worst['seed']} "
          f"{worst['success_rate']:.1%}; wall time median {s['median_wall_time_s']:.0f} s, "
          f"slowest {s['slowest_wall_time_s']:.0f} s (seed {s['slowest_seed']})")
    if out["compared_with"]:
        c = out["compared_with"]
        print(f"against {c['run']}: {c['same_side_of_criterion']}/{len(rows)} seeds on the "
              f"same side of the criterion, {c['same_episodes']}/{len(rows)} with identical episodes")


if __name__ == "__main__":
    main()
