"""The time of one firing of the compiled 1-D dynamics kernel on MicroConveyor-v1's scene (a
benchmark script, not a test).

    python benchmarks/kernel_speed.py [--firings 512] [--repeats 15] [--rounds 3] [--json PATH]
    python benchmarks/kernel_speed.py --compare-with /tmp/base   # a `git worktree` of another commit

The scene is MicroConveyor-v1's (preset ``conveyor``, Gaussian bump, event mode, dt 0.1 ms, at
least 48 RK4 steps a stroke), built as the env builds it. A fixed spread of firings the env fires
(seeded): the part from -0.3 to 0.3 mm of the actuator, half of them at rest and half moving at up
to 0.4 m/s (either way), frequencies 200-2000 Hz (log-uniform), strokes 100-200 µm, no delay,
each one stroke (not coasted to rest). They run through ``physics.batch.simulate_batch`` on the
serial loop (``parallel=False``), whose ``wall_time_s`` is the compiled call alone; the script
reports the time per firing and per RK4 step (the kernel's step count, ``O_STEPS``: event mode
counts each sub-step), min and median over the repeats: in µs on the terminal, in seconds in
the ``--json`` file (keys ``*_s``).

Each round runs in a fresh subprocess (compile caches warm, one untimed call first). With
``--compare-with DIR`` the rounds alternate between this tree (A) and DIR's package (B), so drift
in the machine's load falls on both, and the script reports B's time over A's; it also says
whether both computed bit-identical results (a SHA-256 over every firing's end state, step and
event counts). Timings are noisy on a shared machine: the load averages before and after are
printed with them.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
ENV_ID = "MicroConveyor-v1"


def firings(n: int, seed: int) -> dict[str, Any]:
    """The benchmark's firings (actuator at 0): x0 [m], v0 [m/s], f [Hz], h [m]."""
    import numpy as np
    rng = np.random.default_rng(seed)
    x0 = rng.uniform(-0.3e-3, 0.3e-3, n)
    moving = np.arange(n) % 2 == 1
    v0 = np.where(moving, rng.uniform(-0.4, 0.4, n), 0.0)
    f = np.exp(rng.uniform(np.log(200.0), np.log(2000.0), n))
    h = rng.uniform(100e-6, 200e-6, n)
    return {"x0": x0, "v0": v0, "f": f, "h": h}


def worker(n: int, seed: int, repeats: int) -> dict[str, Any]:
    """Time ``repeats`` serial batches of the firings in this process (the package on sys.path)."""
    import numpy as np

    import microconveyor_env
    from microconveyor_env.envs.core.versions import scene_config
    from microconveyor_env.envs.rail.parts import make_simulator
    from microconveyor_env.physics.batch import simulate_batch

    sim = make_simulator(scene_config(ENV_ID))
    fr = firings(n, seed)
    xa = np.zeros((n, 1))

    def once() -> Any:
        return simulate_batch(sim, xa, fr["f"][:, None], fr["h"][:, None], 0.0, fr["x0"], fr["v0"],
                              parallel=False, to_rest=False)

    res = once()  # compiles or loads the cache
    walls = []
    for _ in range(repeats):
        walls.append(once().wall_time_s)
    digest = hashlib.sha256()
    for a in (res.final_position_m, res.final_velocity_m_s, res.end_time_s, res.steps,
              res.code, res.event_position_m):
        digest.update(np.ascontiguousarray(a).tobytes())
    outcomes, counts = np.unique(res.outcome.astype(str), return_counts=True)
    return {"package": str(Path(microconveyor_env.__file__).parent.parent),
            "wall_s": walls, "steps": int(res.steps.sum()), "firings": n,
            "outcomes": dict(zip(outcomes.tolist(), counts.tolist(), strict=True)),
            "results_sha256": digest.hexdigest()}


def run_worker(root: Path, args: argparse.Namespace) -> dict[str, Any]:
    """One round in a subprocess that imports the package from ``root``."""
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", "--firings",
           str(args.firings), "--seed", str(args.seed), "--repeats", str(args.repeats)]
    done = subprocess.run(cmd, env=env, cwd=str(root), capture_output=True, text=True, check=True)
    rep: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    if Path(rep["package"]).resolve() != root.resolve():
        raise RuntimeError(f"the worker imported {rep['package']}, not {root}")
    return rep


def summary(reps: list[dict[str, Any]]) -> dict[str, Any]:
    """One tree's rounds: times per firing and per RK4 step [s], min and median over repeats."""
    walls = [w for r in reps for w in r["wall_s"]]
    n, steps = reps[0]["firings"], reps[0]["steps"]
    return {"package": reps[0]["package"], "firings": n, "rk4_steps": steps,
            "steps_per_firing": steps / n, "outcomes": reps[0]["outcomes"],
            "results_sha256": reps[0]["results_sha256"],
            "min_firing_time_s": min(walls) / n,
            "median_firing_time_s": statistics.median(walls) / n,
            "min_step_time_s": min(walls) / steps,
            "median_step_time_s": statistics.median(walls) / steps,
            "round_median_firing_time_s": [statistics.median(r["wall_s"]) / n for r in reps]}


def describe(report: dict[str, Any]) -> str:
    """The report in words, times in µs."""
    lines = [f"{report['env_id']}: {report['rounds']} rounds x {report['repeats']} repeats, "
             f"load average {report['load_average_before'][0]:.2f} before, "
             f"{report['load_average_after'][0]:.2f} after ({report['cpu_count']} CPUs)"]
    for name, t in report["trees"].items():
        lines.append(f"{name} {t['package']}: {t['firings']} firings, "
                     f"{t['steps_per_firing']:.1f} RK4 steps each; per firing min "
                     f"{t['min_firing_time_s'] * 1e6:.2f} µs, median "
                     f"{t['median_firing_time_s'] * 1e6:.2f} µs; per step min "
                     f"{t['min_step_time_s'] * 1e6:.3f} µs, median "
                     f"{t['median_step_time_s'] * 1e6:.3f} µs")
    if "B_over_A_median" in report:
        lines.append(f"B / A: {report['B_over_A_median']:.3f} (medians), "
                     f"{report['B_over_A_min']:.3f} (minima); bit-identical results: "
                     f"{report['bit_identical']}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--firings", type=int, default=512, help="firings per batch")
    ap.add_argument("--seed", type=int, default=0, help="seed of the firings' spread")
    ap.add_argument("--repeats", type=int, default=15, help="timed batches per round")
    ap.add_argument("--rounds", type=int, default=3, help="subprocess rounds (per tree)")
    ap.add_argument("--compare-with", type=Path, default=None, metavar="DIR",
                    help="a checkout (git worktree) of another commit: alternate A/B rounds")
    ap.add_argument("--json", type=Path, default=None, metavar="PATH", help="write the report here")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.firings, args.seed, args.repeats)))
        return
    trees = {"A": ROOT}
    if args.compare_with is not None:
        trees["B"] = args.compare_with.resolve()
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    reps: dict[str, list[dict[str, Any]]] = {k: [] for k in trees}
    for _ in range(args.rounds):
        for k, root in trees.items():
            reps[k].append(run_worker(root, args))
    report: dict[str, Any] = {
        "env_id": ENV_ID, "cpu_count": os.cpu_count(), "load_average_before": load_before,
        "load_average_after": os.getloadavg(), "elapsed_s": time.perf_counter() - t0,
        "rounds": args.rounds, "repeats": args.repeats, "seed": args.seed,
        "trees": {k: summary(r) for k, r in reps.items()}}
    if "B" in reps:
        a, b = report["trees"]["A"], report["trees"]["B"]
        report["B_over_A_median"] = b["median_firing_time_s"] / a["median_firing_time_s"]
        report["B_over_A_min"] = b["min_firing_time_s"] / a["min_firing_time_s"]
        report["bit_identical"] = a["results_sha256"] == b["results_sha256"]
    print(describe(report))
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
