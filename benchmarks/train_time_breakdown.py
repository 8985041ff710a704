"""Where the wall time of one PPO training on MicroConveyor-v1 goes, as
``microconveyor train --env MicroConveyor-v1 --refine`` runs it, shortened to ``--steps``.

    taskset -c 1 python benchmarks/train_time_breakdown.py [--steps 409600] [--refine-rounds 1]
        [--refine-policy agents/policies/MicroConveyor-v1/ppo | run] [--no-progress]
        [--json docs/figures/train_time_breakdown.json]

One training with ``configs/ppo.yml``'s MicroConveyor-v1 recipe (256 envs x 16 steps, batches of
1,024, 10 epochs, the exploration restart and shift at their fractions of ``--steps``) and the
command's defaults (seed 0, progress bar, tensorboard logs, a checkpoint every 200,000 steps, an
evaluation on 100 fixed targets every 250,000 steps and one at the end), into a temporary folder;
then the refinement ``--refine`` does (``refine`` on the final policy, the refined policy
evaluated on 100 targets and written), with ``--refine-rounds`` rounds instead of the default 8;
then the same refinement of a 6 M-step policy of the recipe (``--refine-policy``, default the
shipped ``agents/policies/MicroConveyor-v1/ppo``: a round's cost depends on the policy refined,
and the full recipe refines a 6 M-step one).

The time is split by wrapping methods of the live objects (``time.perf_counter`` and
``time.process_time`` accumulators: wall and this process's CPU time; each part counts its own
time, without the parts nested in it):

- env stepping: ``VecNormalize.step`` of the training env, split into the compiled batched env's
  ``step``, the SB3 adapter around it (per-env info dicts), VecMonitor and VecNormalize;
- policy inference: the policy's ``forward`` and ``predict_values`` inside ``collect_rollouts``;
- rollout bookkeeping: the rest of ``collect_rollouts``: the rollout buffer (``add``,
  ``compute_returns_and_advantage``, ``reset``), the callbacks' ``on_step`` (progress bar,
  the checkpoint/evaluation schedule), and the loop itself (tensor conversion, action clipping,
  episode-info buffer, time-limit checks);
- gradient updates: ``PPO.train`` (10 epochs of 4 minibatches per rollout);
- logging: ``dump_logs`` after each rollout (tensorboard);
- periodic evaluation: the trainer's ``run_eval`` (100 targets), per evaluation;
- checkpoints: ``save_checkpoint`` (every 200,000 steps and the final save);
- setup and other: the rest of the training call (env and model construction, first reset,
  the final files);
- refinement: loading the final policy, the score as given and each round (timed from
  ``refine``'s own progress lines; refine's time also split into its closed-loop episodes, the
  Newton corrections and the actor's L-BFGS fit), the evaluation of the refined policy and its
  writing.

The extrapolation to the recipe's 6 M steps scales the per-rollout parts by the number of
rollouts, the evaluations and checkpoints by how many the trainer's schedule makes in 6 M steps
(at the measured cost of one), keeps setup as measured, and takes the refinement of the 6 M-step
policy at its default 8 rounds as its measured steps outside the rounds plus 8 times its mean
measured round (the CPU times likewise, the refinement's in proportion to its wall time). The
policy and the env's cost per step change as training goes on, so the extrapolation is an
estimate.

Torch runs on 1 thread and the env on its serial loop (the recipe's ``num_threads: 1``); pin the
process to one core (``taskset -c 1``). A warm-up (a 4,096-step training, an evaluation and a tiny
refinement) loads numba's and torch's caches first; its time is reported but not in the table.
The machine's load averages before and after are recorded: on a shared machine the seconds are
upper bounds and the shares within the one run are what the script measures (the CPU column
leaves out the time the process waited for the core). Prints a table and writes JSON (SI units,
unit-suffixed keys).
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
from collections import defaultdict
from datetime import datetime, UTC
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import torch

from agents.rl.evaluation.evaluate import evaluate, load_policy
from agents.rl.refinement.refine import refine
from agents.rl.refinement.settings import RefineSettings
from agents.rl.refinement.writer import write_refined
from agents.rl.training import hyperparams
from agents.rl.training import train as T
from agents.rl.training.settings import TrainSettings
from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

ENV_ID = "MicroConveyor-v1"
ROOT = Path(__file__).resolve().parent.parent
DEFAULT_JSON = ROOT / "docs" / "figures" / "train_time_breakdown.json"
SHIPPED = ROOT / "agents" / "policies" / ENV_ID / "ppo"   # the recipe's 6 M-step policy, seed 0

# the parts, in table order: key, label, how the 6 M-step extrapolation scales it
PARTS = [
    ("env_compiled", "  compiled batched env step", "rollouts"),
    ("env_adapter", "  SB3 adapter (info dicts)", "rollouts"),
    ("env_monitor", "  VecMonitor", "rollouts"),
    ("env_normalize", "  VecNormalize", "rollouts"),
    ("inference", "policy inference (rollouts)", "rollouts"),
    ("buffer", "  rollout buffer", "rollouts"),
    ("callbacks", "  callbacks' on_step", "rollouts"),
    ("rollout_loop", "  rollout loop (rest)", "rollouts"),
    ("updates", "gradient updates (PPO.train)", "rollouts"),
    ("logging", "logging (dump_logs)", "rollouts"),
    ("evaluation", "periodic evaluation", "evaluations"),
    ("checkpoints", "checkpoints", "checkpoints"),
    ("setup", "setup and other", "fixed"),
    ("refinement", "refinement", "refinement"),
]
GROUPS = {"env_step": ("env stepping",
                       ("env_compiled", "env_adapter", "env_monitor", "env_normalize")),
          "bookkeeping": ("rollout bookkeeping", ("buffer", "callbacks", "rollout_loop"))}


class Clock:
    """Exclusive wall and CPU time per part: a wrapped call's time, less that of the wrapped
    calls nested in it, goes to its part."""

    def __init__(self) -> None:
        self.s: dict[str, float] = defaultdict(float)        # wall [s]
        self.cpu_s: dict[str, float] = defaultdict(float)    # this process's CPU [s]
        self.calls: dict[str, int] = defaultdict(int)
        self.per_call: dict[str, list[float]] = defaultdict(list)  # inclusive wall, rare parts
        self.stack: list[list[Any]] = []

    def wrap(self, obj: Any, name: str, part: str, under: tuple[str, ...] | None = None,
             keep: bool = False) -> None:
        """Replace ``obj.name`` by a timed call charged to ``part``; with ``under``, only while
        the innermost timed call is one of those parts (otherwise untimed)."""
        f = getattr(obj, name)

        def timed(*a: Any, **k: Any) -> Any:
            if under is not None and (not self.stack or self.stack[-1][0] not in under):
                return f(*a, **k)
            frame: list[Any] = [part, 0.0, 0.0]
            self.stack.append(frame)
            t, c = time.perf_counter(), time.process_time()
            try:
                return f(*a, **k)
            finally:
                dt, dc = time.perf_counter() - t, time.process_time() - c
                self.stack.pop()
                self.s[part] += dt - frame[1]
                self.cpu_s[part] += dc - frame[2]
                self.calls[part] += 1
                if keep:
                    self.per_call[part].append(dt)
                if self.stack:
                    self.stack[-1][1] += dt
                    self.stack[-1][2] += dc

        setattr(obj, name, timed)


def instrument(model: Any, periodic: Any, clock: Clock) -> None:
    """Wrap the methods of the live model, its env, policy, buffer and callbacks."""
    wrapped = ["collect_rollouts", "train", "dump_logs", "_init_callback"]
    clock.wrap(model, "collect_rollouts", "rollout_loop")
    clock.wrap(model, "train", "updates")
    clock.wrap(model, "dump_logs", "logging")
    vn = model.env                      # VecNormalize(VecMonitor(adapter))
    adapter = vn
    while not isinstance(adapter, MicroConveyorSB3VecEnv):
        adapter = adapter.venv
    clock.wrap(vn, "step", "env_normalize", under=("rollout_loop",))
    inner = vn.venv                     # VecMonitor (and any training wrappers of the recipe)
    while inner is not adapter:
        clock.wrap(inner, "step_wait", "env_monitor", under=("env_normalize", "env_monitor"))
        inner = inner.venv
    clock.wrap(adapter, "step_wait", "env_adapter", under=("env_normalize", "env_monitor"))
    clock.wrap(adapter.venv, "step", "env_compiled", under=("env_adapter",))
    for name in ("forward", "predict_values"):
        clock.wrap(model.policy, name, "inference", under=("rollout_loop",))
    for name in ("add", "compute_returns_and_advantage", "reset"):
        clock.wrap(model.rollout_buffer, name, "buffer", under=("rollout_loop",))
    clock.wrap(periodic, "run_eval", "evaluation", keep=True)
    clock.wrap(periodic, "save_checkpoint", "checkpoints", keep=True)

    init_callback = model._init_callback

    def init_timed(*a: Any, **k: Any) -> Any:
        cb = init_callback(*a, **k)     # the CallbackList learn() steps
        clock.wrap(cb, "on_step", "callbacks", under=("rollout_loop",))
        return cb

    model._init_callback = init_timed
    # the model's saves must not pickle the wrappers (instance attributes now)
    excluded = model._excluded_save_params
    model._excluded_save_params = lambda: [*excluded(), *wrapped, "_excluded_save_params"]


def schedule(total: int, n_envs: int, n_steps: int, eval_freq: int, ckpt_freq: int
             ) -> dict[str, int]:
    """The trainer's step count, evaluations and checkpoints for a run of ``total`` steps:
    learn() collects whole rollouts until ``total`` is reached; the callback checks after each
    env step; the end adds an evaluation unless one fell on the last step, and a final save."""
    per_rollout = n_envs * n_steps
    rollouts = -(-total // per_rollout)
    n, next_eval, next_ckpt, evals, ckpts, last_eval = 0, eval_freq, ckpt_freq, 0, 0, -1
    for _ in range(rollouts * n_steps):
        n += n_envs
        if eval_freq and n >= next_eval:
            next_eval += eval_freq
            evals, last_eval = evals + 1, n
        if n >= next_ckpt:
            next_ckpt += ckpt_freq
            ckpts += 1
    return {"steps": n, "rollouts": rollouts, "evaluations": evals + (last_eval != n),
            "checkpoints": ckpts + 1}


def train_once(out: Path, steps: int, clock: Clock | None, progress: bool,
               eval_targets: int = 100, eval_freq: int = 250_000) -> dict:
    """One training as ``microconveyor train --env MicroConveyor-v1`` runs it (its defaults),
    instrumented through ``clock``; returns the metadata and the wall time [s]."""
    def instrumented(model: Any, periodic: Any) -> None:
        if clock is not None:
            instrument(model, periodic, clock)

    settings = TrainSettings(env_id=ENV_ID, steps=steps, eval_freq=eval_freq,
                             eval_targets=eval_targets, progress_bar=progress,
                             tensorboard=clock is not None)
    t0, c0 = time.perf_counter(), time.process_time()
    meta = T.train(out, settings, on_model=instrumented)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"meta": meta, "wall_s": wall, "cpu_s": cpu}


def refine_once(policy: Path, out: Path, rounds: int, eval_targets: int = 100,
                **kw: Any) -> dict:
    """What ``train --refine`` does after training, on the policy folder ``policy``, with
    ``rounds`` rounds, the refined policy written to ``out``: times [s] of each step, the rounds
    from refine's progress lines, and refine's wall time split into its episodes (the scores and
    each round's closed-loop play), the Newton corrections and the actor's fit."""
    import agents.rl.refinement.refine as refine_module

    marks: list[float] = []
    clock = Clock()
    ns = SimpleNamespace(refine=refine)
    clock.wrap(ns, "refine", "other")
    undo = [(refine_module.corrections, "play"), (refine_module.corrections, "labelled_episodes"),
            (refine_module.fitting, "fit")]
    saved = [getattr(m, n) for m, n in undo]
    clock.wrap(refine_module.corrections, "play", "episodes", under=("other",))
    clock.wrap(refine_module.corrections, "labelled_episodes", "corrections", under=("other",))
    clock.wrap(refine_module.fitting, "fit", "fit", under=("other",))
    c0 = time.process_time()
    t = [time.perf_counter()]
    try:
        pol = load_policy(policy)
        t.append(time.perf_counter())
        threads = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            report = ns.refine(pol, RefineSettings(rounds=rounds, **kw),
                               log=lambda line: marks.append(time.perf_counter()))
        finally:
            torch.set_num_threads(threads)
    finally:
        for (m, n), f in zip(undo, saved, strict=True):
            setattr(m, n, f)
    t.append(time.perf_counter())
    before = pol.metadata.get("evaluation") or {}
    ev = evaluate(pol, eval_targets, int(before.get("seed", 12345))) if eval_targets else None
    t.append(time.perf_counter())
    write_refined(pol, report, out, ev)
    t.append(time.perf_counter())
    cpu = time.process_time() - c0
    # marks: after the score as given, after each round, after restoring the best round
    rounds_s = [b - a for a, b in zip(marks[:-2], marks[1:-1], strict=True)]
    return {"policy": str(policy), "load_s": t[1] - t[0], "score_as_given_s": marks[0] - t[1],
            "rounds_s": rounds_s, "finish_s": t[2] - marks[-2], "refine_s": t[2] - t[1],
            "refine_parts_s": dict(clock.s), "evaluation_s": t[3] - t[2],
            "write_s": t[4] - t[3], "total_s": t[4] - t[0], "cpu_s": cpu,
            "corrected": [r.get("corrected") for r in report["rounds"][1:]],
            "kept_round": report["kept_round"]}


def refine_estimate(rf: dict, rounds: int) -> float:
    """The wall time [s] of the refinement at ``rounds`` rounds from a measured one: its steps
    outside the rounds as measured, plus ``rounds`` times its mean round."""
    mean = sum(rf["rounds_s"]) / len(rf["rounds_s"])
    return (rf["load_s"] + rf["score_as_given_s"] + rounds * mean + rf["finish_s"]
            + rf["evaluation_s"] + rf["write_s"])


def _cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo ('' where there is none)."""
    try:
        with open("/proc/cpuinfo") as fh:
            return next((ln.split(":", 1)[1].strip() for ln in fh
                         if ln.startswith("model name")), "")
    except OSError:
        return ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=409_600,
                    help="training steps (default 409,600: 100 rollouts of 4,096)")
    ap.add_argument("--refine-rounds", type=int, default=1,
                    help="refinement rounds run (the default refinement has 8; the estimate "
                         "scales the mean round to 8)")
    ap.add_argument("--refine-policy", default=str(SHIPPED),
                    help="a 6 M-step policy folder of the recipe whose refinement (same rounds) "
                         "the 6 M-step estimate takes ('run': this run's own policy; default: "
                         "the shipped MicroConveyor-v1 ppo policy)")
    ap.add_argument("--no-progress", action="store_true",
                    help="no progress bar (the command shows one by default)")
    ap.add_argument("--json", default=str(DEFAULT_JSON), help="where to write the result")
    args = ap.parse_args()

    load_before = os.getloadavg()
    hp = hyperparams.load(None, ENV_ID, "ppo")
    n_envs, n_steps = int(hp["n_envs"]), int(hp["n_steps"])
    full_steps = int(hp["n_timesteps"])
    defaults = TrainSettings()
    run_plan = schedule(args.steps, n_envs, n_steps, defaults.eval_freq, defaults.checkpoint_freq)
    full_plan = schedule(full_steps, n_envs, n_steps, defaults.eval_freq,
                         defaults.checkpoint_freq)
    default_rounds = RefineSettings().rounds

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()   # warm-up: numba's compiled functions, torch, the eval path
        train_once(Path(tmp) / "warm", n_envs * n_steps, None, False, eval_targets=4,
                   eval_freq=0)
        refine_once(Path(tmp) / "warm", Path(tmp) / "warm" / "refined", 1, eval_targets=4,
                    targets=16, fit_iterations=2)
        warmup_s = time.perf_counter() - t0

        clock = Clock()
        run = Path(tmp) / "run"
        tr = train_once(run, args.steps, clock, not args.no_progress)
        rf = refine_once(run, run / "refined", args.refine_rounds)
        rs = rf if args.refine_policy == "run" else refine_once(
            Path(args.refine_policy), Path(tmp) / "refined_6M", args.refine_rounds)
    load_after = os.getloadavg()

    clock.s["setup"] = tr["wall_s"] - sum(clock.s.values())
    clock.s["refinement"] = rf["total_s"]
    clock.cpu_s["setup"] = tr["cpu_s"] - sum(clock.cpu_s.values())
    clock.cpu_s["refinement"] = rf["cpu_s"]
    refine_full = refine_estimate(rs, default_rounds)
    n_evals, n_ckpts = clock.calls["evaluation"], clock.calls["checkpoints"]
    rollout_ratio = full_plan["rollouts"] / run_plan["rollouts"]

    def estimate(acc: dict[str, float]) -> dict[str, float]:
        """The parts of ``acc`` (wall or CPU [s]) for the 6 M-step recipe."""
        out = {}
        for k, _, how in PARTS:
            if how == "rollouts":
                out[k] = acc[k] * rollout_ratio
            elif how in ("evaluations", "checkpoints"):
                out[k] = acc[k] / max(clock.calls[k], 1) * full_plan[how]
            elif how == "refinement":
                out[k] = refine_full * (rs["cpu_s"] / rs["total_s"] if acc is clock.cpu_s else 1)
            else:
                out[k] = acc[k]
        return out

    per = {k: clock.s[k] / max(clock.calls[k], 1) for k in ("evaluation", "checkpoints")}
    run_s = {k: clock.s[k] for k, _, _ in PARTS}
    cpu_s = {k: clock.cpu_s[k] for k, _, _ in PARTS}
    full_s, full_cpu_s = estimate(clock.s), estimate(clock.cpu_s)
    for g, (_, keys) in GROUPS.items():
        for d in (run_s, cpu_s, full_s, full_cpu_s):
            d[g] = sum(d[k] for k in keys)
    run_total = tr["wall_s"] + rf["total_s"]
    cpu_total = tr["cpu_s"] + rf["cpu_s"]
    full_total = sum(full_s[k] for k, _, _ in PARTS)
    full_cpu_train = sum(full_cpu_s[k] for k, _, _ in PARTS if k != "refinement")

    # the table
    label_of = {k: lab for k, lab, _ in PARTS}
    order = ["env_step", "env_compiled", "env_adapter", "env_monitor", "env_normalize", "inference",
             "bookkeeping", "buffer", "callbacks", "rollout_loop", "updates", "logging",
             "evaluation", "checkpoints", "setup", "refinement"]
    label_of.update({g: lab for g, (lab, _) in GROUPS.items()})
    note = {"evaluation": f"{n_evals} here, {full_plan['evaluations']} in 6 M "
                          f"({per['evaluation']:.2f} s each)",
            "checkpoints": f"{n_ckpts} here, {full_plan['checkpoints']} in 6 M "
                           f"({per['checkpoints']:.2f} s each)",
            "refinement": f"{args.refine_rounds} round(s) here; 6 M: {default_rounds} rounds"
                          + ("" if rs is rf else " of the 6 M-step policy's")}
    steps_done = int(tr["meta"]["steps"])
    print(f"{ENV_ID}, PPO (configs/ppo.yml), torch threads {torch.get_num_threads()}, "
          f"cores {sorted(os.sched_getaffinity(0))} of {os.cpu_count()}; "
          f"load {load_before[0]:.2f} before, {load_after[0]:.2f} after")
    print(f"{'':32} {f'this run, {steps_done:,} steps: wall, CPU':>32} "
          f"{'6 M steps (est.), wall':>24}")
    print(f"{'part':32} {'s':>7} {'share':>7} {'s':>8} {'share':>7} {'s':>15} {'share':>8}")

    def row(label: str, w: float, c: float, f: float, extra: str = "") -> None:
        print(f"{label:32} {w:>7.1f} {w / run_total:>7.1%} {c:>8.1f} {c / cpu_total:>7.1%} "
              f"{f:>15.0f} {f / full_total:>8.1%}" + (f"   {extra}" if extra else ""))

    for k in order:
        row(label_of[k], run_s[k], cpu_s[k], full_s[k], note.get(k, ""))
    row("total", run_total, cpu_total, full_total)
    train_full = full_total - refine_full
    print(f"training: {tr['wall_s']:.1f} s here ({steps_done / tr['wall_s']:,.0f} steps/s, CPU "
          f"{tr['cpu_s']:.1f} s); estimated for 6 M: {train_full:.0f} s "
          f"({train_full / 60:.1f} min) wall, {full_cpu_train:.0f} s "
          f"({full_cpu_train / 60:.1f} min) CPU")
    refined = [("this run's policy", rf)] + ([] if rs is rf else [(args.refine_policy, rs)])
    for name, r in refined:
        parts = ", ".join(f"{k} {v:.1f}" for k, v in r["refine_parts_s"].items())
        print(f"refinement of {name}: {r['total_s']:.1f} s for {args.refine_rounds} round(s), "
              f"{refine_estimate(r, default_rounds):.0f} s estimated at {default_rounds}: load "
              f"{r['load_s']:.1f} s, score as given {r['score_as_given_s']:.1f} s, round(s) "
              f"{', '.join(f'{x:.1f}' for x in r['rounds_s'])} s (refine's parts [s]: {parts}), "
              f"evaluation {r['evaluation_s']:.2f} s, writing {r['write_s']:.2f} s")
    print(f"warm-up {warmup_s:.1f} s (not counted)")

    aff = sorted(os.sched_getaffinity(0))
    prefix = f"taskset -c {','.join(map(str, aff))} " if len(aff) < (os.cpu_count() or 1) else ""
    result = {
        "env_id": ENV_ID,
        "recipe": {"n_envs": n_envs, "n_steps": n_steps, "batch_size": int(hp["batch_size"]),
                   "n_epochs": int(hp["n_epochs"]), "n_timesteps": full_steps,
                   "eval_freq_steps": defaults.eval_freq, "eval_targets": defaults.eval_targets,
                   "checkpoint_freq_steps": defaults.checkpoint_freq,
                   "refine_rounds_default": default_rounds},
        "run": {"steps": steps_done, "rollouts": run_plan["rollouts"],
                "evaluations": n_evals, "checkpoints": n_ckpts,
                "refine_rounds": args.refine_rounds, "progress_bar": not args.no_progress,
                "training_wall_s": tr["wall_s"], "total_s": run_total,
                "parts_s": run_s, "shares": {k: v / run_total for k, v in run_s.items()},
                "training_cpu_s": tr["cpu_s"], "cpu_total_s": cpu_total, "parts_cpu_s": cpu_s,
                "cpu_shares": {k: v / cpu_total for k, v in cpu_s.items()},
                "schedule": run_plan,
                "calls": dict(clock.calls),
                "evaluation_each_s": clock.per_call["evaluation"],
                "checkpoint_each_s": clock.per_call["checkpoints"],
                "refinement": rf,
                "final_evaluation": tr["meta"].get("evaluation")},
        "full_recipe_estimate": {
            "steps": full_plan["steps"], "rollouts": full_plan["rollouts"],
            "evaluations": full_plan["evaluations"], "checkpoints": full_plan["checkpoints"],
            "evaluation_each_s": per["evaluation"], "checkpoint_each_s": per["checkpoints"],
            "refinement_s": refine_full, "refinement_measured": rs,
            "training_s": full_total - refine_full,
            "total_s": full_total, "parts_s": full_s,
            "shares": {k: v / full_total for k, v in full_s.items()},
            "training_cpu_s": full_cpu_train, "parts_cpu_s": full_cpu_s,
            "how": "per-rollout parts x rollouts ratio; evaluations and checkpoints x their "
                   "count in 6 M steps at the measured cost of one; setup as measured; "
                   "refinement = load + score as given + default rounds x mean measured round "
                   "+ evaluation + write (its CPU in proportion)"},
        "warmup_s": warmup_s,
        "machine": {"cpu_count": os.cpu_count(), "processor": platform.processor(),
                    "cpu_model": _cpu_model(),
                    "machine": platform.machine(), "cpu_affinity": aff,
                    "torch_threads": torch.get_num_threads(), "torch": torch.__version__,
                    "load_average_before": list(load_before),
                    "load_average_after": list(load_after)},
        "recorded_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": prefix + shlex.join(["python", *sys.argv]),
    }
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=1, default=float) + "\n")
    print(f"-> {args.json}")


if __name__ == "__main__":
    main()
