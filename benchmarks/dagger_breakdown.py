"""Where the wall time of one DAgger training goes, as ``microconveyor imitate --env ID`` runs
it (the recipe of ``configs/dagger.yml``), by part (a benchmark script, not a test).

    taskset -c 1 python benchmarks/dagger_breakdown.py [--env MicroPositioner-v0] [--seed 0]
        [--rounds R] [--episodes N] [--json docs/figures/dagger_breakdown_positioner.json]

One training with the recipe's settings (``--rounds``/``--episodes`` shorten it), its policy
folder written to a temporary folder (counted in "setup and other") and removed. The time is split by wrapping methods of the live objects, each part counting its own
time without the parts nested in it (``Clock`` of ``train_time_breakdown.py``; wall and this
process's CPU time):

- expert construction: ``make_expert`` (the scene's firing map built or loaded from the disk
  cache, the seed policy loaded; numba's compiled code loaded);
- expert labelling: the expert's ``label`` on every state visited;
- env stepping: the batched env's ``step`` and ``reset``;
- student acting: the network's forward passes in the rounds where the policy acts;
- fitting: the regression after each round (Adam epochs or L-BFGS);
- setup and other: the rest (env, expert and network construction, data concatenation).

Torch runs on one thread and the env on its serial loop (the recipe's); pin the process to one
core. The machine's load averages before and after are recorded: on a shared machine the seconds
are upper bounds and the shares within the run are what the script measures. Prints a table and
writes JSON (SI units, unit-suffixed keys).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from agents.imitation import dagger as D
from agents.imitation.student import Student
from microconveyor_env.envs.core.versions import vector_class


def _clock_class() -> Any:
    """``Clock`` of ``train_time_breakdown.py`` beside this file: the same exclusive-time
    accounting."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "train_time_breakdown", Path(__file__).with_name("train_time_breakdown.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.Clock

PARTS = [("expert_setup", "expert construction"), ("expert", "expert labelling"), ("env", "env stepping (batched env)"),
         ("student_act", "student acting (forward passes)"), ("fit", "fitting the network"),
         ("other", "setup and other")]
DAGGER_ENV_IDS = ("MicroPositioner-v0", "MicroConveyor-v1", "MicroConveyor2D-v1")


def instrument(env_id: str, clock: Any) -> None:
    """Wrap the batched env's class, the student's class and the expert ``make_expert``
    returns (before the training builds them)."""
    venv_cls = vector_class(env_id)
    clock.wrap(venv_cls, "step", "env")
    clock.wrap(venv_cls, "reset", "env")
    clock.wrap(Student, "act", "student_act")
    clock.wrap(Student, "fit", "fit")
    make_expert = D.make_expert

    def timed_make_expert(s: Any, cfg: Any) -> Any:
        label, meta = make_expert(s, cfg)
        holder = type("Expert", (), {})()
        holder.label = label
        clock.wrap(holder, "label", "expert")
        return holder.label, meta

    holder = type("Maker", (), {})()
    holder.make = timed_make_expert
    clock.wrap(holder, "make", "expert_setup")
    D.make_expert = holder.make


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="MicroPositioner-v0", choices=DAGGER_ENV_IDS)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=None, help="default: the recipe's")
    ap.add_argument("--episodes", type=int, default=None, help="default: the recipe's")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    a = ap.parse_args(argv)
    over: dict[str, Any] = {"seed": a.seed}
    if a.rounds is not None:
        over["rounds"] = a.rounds
    if a.episodes is not None:
        over["episodes"] = a.episodes
    s = D.recipe(a.env, **over)
    clock = _clock_class()()
    instrument(a.env, clock)
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), time.process_time()
        meta = D.dagger(Path(tmp) / "policy", s, lambda line: print(line, flush=True))
        total, total_cpu = time.perf_counter() - t0, time.process_time() - c0
    load_after = os.getloadavg()
    named = [k for k, _ in PARTS if k != "other"]
    parts = {k: {"wall_s": clock.s[k], "cpu_s": clock.cpu_s[k], "calls": clock.calls[k]}
             for k in named}
    parts["other"] = {"wall_s": total - sum(clock.s[k] for k in named),
                      "cpu_s": total_cpu - sum(clock.cpu_s[k] for k in named), "calls": 1}
    last = meta["rounds"][-1]
    out = {"env_id": a.env, "seed": a.seed, "rounds": s.rounds, "episodes_per_round": s.episodes,
           "samples": last["samples"], "final_round_success_rate": last["success_rate"],
           "final_round_median_abs_error_m": last["median_abs_error_m"],
           "total_wall_s": total, "total_cpu_s": total_cpu, "parts": parts,
           "load_average_before": list(load_before), "load_average_after": list(load_after),
           "machine": {"cpu_count": os.cpu_count(), "processor": platform.processor(),
                       "python": platform.python_version()},
           "date": datetime.now(UTC).strftime("%Y-%m-%d"),
           "command": shlex.join(["python", "benchmarks/dagger_breakdown.py",
                                  *(sys.argv[1:] if argv is None else argv)])}
    print(f"\n{a.env}, seed {a.seed}: {s.rounds} rounds x {s.episodes} episodes, "
          f"{total:.1f} s wall, {total_cpu:.1f} s CPU (load {load_before[0]:.1f} -> "
          f"{load_after[0]:.1f})")
    print(f"{'part':<34}{'wall [s]':>10}{'share':>8}{'CPU [s]':>10}{'calls':>8}")
    for key, label in PARTS:
        p = parts[key]
        print(f"{label:<34}{p['wall_s']:>10.1f}{p['wall_s'] / total:>8.0%}{p['cpu_s']:>10.1f}"
              f"{p['calls']:>8}")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {a.json}")
    return out


if __name__ == "__main__":
    main()
