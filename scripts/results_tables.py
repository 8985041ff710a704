"""The tables of README.md and docs/ that repeat a stored result, generated from that result.

A generated table sits between two markers, ``<!-- results:NAME -->`` and
``<!-- /results:NAME -->``; this script rewrites what is between them from the stored JSON:

* ``answer``: the answer table (target distance → method → error and placement time, nominal
  and under execution noise) from ``docs/figures/answer_table.json``
  (``scripts/answer_table.py`` measures it);
* ``noise``: that table's noise level in action units and as frequency, stroke and delay jitter;
* ``shipped``: every shipped policy's recorded evaluations, from its ``metadata.json``
  (``microconveyor record`` records them);
* ``compare``: the comparison of every method on MicroConveyor-v1 under perturbation, from
  ``docs/figures/compare_v1_mpc_ppo.json`` (``microconveyor compare --mpc-prior .../ppo``);
* ``plane``: the shipped plane policy against DE, from ``docs/figures/plane_v0_errors.json``;
* ``threads``: SB3's SAC with torch's default threads and with one, from
  ``docs/figures/sac_threads.json`` (``scripts/sac_threads.py``);
* ``seeds``: training seeds' final checkpoints, IQM and bootstrap interval, from the
  ``microconveyor seeds --json`` outputs stored in ``docs/figures/*seeds.json``;
* ``imitate_v1_nothing``: the same for v1's recipe from the simulator alone, from
  ``docs/figures/imitate_v1_nothing_seeds.json``;
* ``positioner_compare``: every method on MicroPositioner-v0 under perturbation, from
  ``docs/figures/compare_positioner.json`` (``microconveyor compare --env MicroPositioner-v0``);
* ``positioner_sizing``: MicroPositioner-v0's spacing study, from
  ``docs/figures/positioner_sizing.json`` (``scripts/positioner_sizing.py``);
* ``positioner_seeds``: its policies per training seed and their IQM, from
  ``docs/figures/positioner_seeds.json`` (``scripts/positioner_policies.py``);
* ``firing_maps``: each scene's firing map against the full model, from
  ``docs/figures/firing_maps.json`` (``microconveyor firing-map --json``);
* ``planner_speed``: MPC per target before and after the fast planners, from
  ``docs/figures/planner_speed.json`` (``scripts/planner_speed.py``);
* ``frontier_line``, ``frontier_positioner``, ``frontier_plane``: precision against placement
  time per method and request, from ``docs/figures/frontier_*.json`` (``scripts/frontier.py``);
  ``frontier_answer``: the fastest method holding each request, from the same;
* ``v1_fast``: MicroConveyor-v1's recipe per training seed with placement times and the lower
  bound, from ``docs/figures/v1_fast.json``;
* ``request_seeds``: the policies that take the requested tolerance as an input, per scene,
  level and request, from ``docs/figures/request_seeds.json``;
* ``dagger_breakdown``: where each DAgger recipe's time goes, from
  ``docs/figures/dagger_breakdown_*.json`` (``benchmarks/dagger_breakdown.py``).

::

    python scripts/results_tables.py            # rewrite the regions in place
    python scripts/results_tables.py --check    # exit 1, naming each region that differs
    python scripts/results_tables.py --root DIR # rewrite DIR/README.md and DIR/docs/*.md instead

``tests/test_results_tables.py`` fails when a region differs from what this script writes.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "figures"   # every stored result JSON lives beside its figures
POLICIES = ROOT / "agents" / "policies"
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
REGION = re.compile(r"(<!-- results:(?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /results:(?P=name) -->)",
                    re.S)
METHOD_NAMES = {"ppo_refined": "the shipped policy `ppo_refined`",
                "mpc_ppo_refined": "MPC seeded by `ppo_refined`",
                "de": "DE per target, 1,000 episodes (open loop)"}
EVALUATIONS = {"evaluation": "monitored", "evaluation_fresh": "fresh",
               "evaluation_nominal": "nominal (randomisation off)"}


def _um(x_m: float) -> str:
    v = x_m * 1e6
    return f"{v:.1f} µm" if v < 100 else f"{v:,.0f} µm"


def _command(data: dict) -> str:
    """A benchmark's stored command without its ``--note`` (the note is shown on its own)."""
    return re.sub(r" --note .*$", "", data["command"])


def _small_m(x_m: float) -> str:
    """A length that may be far below a micrometre (a difference between two runs)."""
    return f"{x_m * 1e9:.1f} nm" if x_m < 1e-6 else _um(x_m)


def _ms(x_s: float) -> str:
    return f"{x_s * 1e3:.1f} ms" if x_s < 1 else f"{x_s:.1f} s"


def wilson(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval of k successes in n trials."""
    from agents.experiments import perturb

    lo, hi = perturb.wilson(k, n)
    return lo, hi


def _cell(episodes: list[dict], tol: float) -> str:
    import numpy as np

    err = np.abs([e["error_m"] for e in episodes])
    ok = sum(bool(e["outcome"] == "rest" and abs(e["error_m"]) <= tol) for e in episodes)
    return f"{_um(float(np.median(err)))} ({100 * ok / len(episodes):.0f} %)"


def _times(median_s: float | None, p90_s: float | None = None) -> str:
    """A placement time's median and 90th percentile [s] as ``median / p90 ms``: the median alone
    where no percentile is stored, a dash where no part rested (or no time is stored)."""
    if median_s is None:
        return "–"
    if p90_s is None:
        return f"{median_s * 1e3:.1f} ms"
    return f"{median_s * 1e3:.1f} / {p90_s * 1e3:.1f} ms"


def _episode_times(time_s: list | None, outcome: list) -> str:
    """:func:`_times` of episodes' placement times [s] over those that ended at rest
    (:func:`agents.rl.evaluation.evaluate.placement_times`); a dash where none is stored."""
    from agents.rl.evaluation.evaluate import placement_times

    if time_s is None:
        return "–"
    t = placement_times(time_s, outcome)
    return _times(t["median_placement_time_s"], t["p90_placement_time_s"])


def _time_cell(episodes: list[dict]) -> str:
    times = [e.get("time_s") for e in episodes]
    return _episode_times(None if None in times else times, [e["outcome"] for e in episodes])


def _load(provenance: dict) -> str:
    """The load average a stored measurement ran under, where it was recorded."""
    load = provenance.get("load_average")
    return "" if load is None else f" (load average {min(load):.1f}–{max(load):.1f} while measured)"


def answer_table(data: dict) -> str:
    tol = data["tolerance_m"]
    n_t, n_s = data["targets_per_distance"], data["noise_seeds"]
    sigma = data["noise"]["sigma_action_units"]
    lines = [f"| target | method | nominal: median \\|error\\| (within ±{tol * 1e6:.0f} µm) | "
             f"nominal: placement time | under noise σ = {sigma:g} | under noise: placement "
             "time | compute per target |", "|---|---|---|---|---|---|---|"]
    for d in data["distances_m"]:
        for name, m in data["methods"].items():
            def near(rows: list[dict], d: float = d) -> list[dict]:
                return [r for r in rows if abs(r["target_m"] - d) <= 0.2e-3]
            lines.append(f"| {d * 1e3:g} mm | {METHOD_NAMES[name]} | {_cell(near(m['nominal']), tol)} | "
                         f"{_time_cell(near(m['nominal']))} | {_cell(near(m['noise']), tol)} | "
                         f"{_time_cell(near(m['noise']))} | {_ms(m['wall_s_per_target'])} |")
    lines.append("")
    lines.append(f"{data['env_id']}; per distance d, {n_t} targets over d ± 0.1 mm; nominal: one "
                 f"episode per target; under noise: {n_s} noise seeds per target "
                 f"({n_t * n_s} episodes per cell). Median absolute final error, in brackets the "
                 f"share at rest within ±{tol * 1e6:.0f} µm; placement time: the simulated time "
                 "until the part rests, median / 90th percentile over the parts at rest; compute: "
                 f"wall time on the machine of docs/results.md{_load(data['provenance'])}. "
                 f"Reproduce: `{data['provenance']['command']}`.")
    return "\n".join(lines)


def noise_table(data: dict) -> str:
    n = data["noise"]
    return "\n".join([
        "| σ [action units] | frequency (1 σ) | stroke (1 σ) | delay (1 σ) |",
        "|---|---|---|---|",
        f"| {n['sigma_action_units']:g} | {100 * n['frequency_relative']:.2f} % "
        f"({n['frequency_at_1khz_hz']:.1f} Hz at 1 kHz) | {n['stroke_m'] * 1e6:.2f} µm | "
        f"{n['delay_s'] * 1e6:.0f} µs |"])


def shipped_rows() -> list[dict]:
    """Every recorded evaluation of every shipped policy: env id, name, which evaluation, the
    evaluation dict and the metadata."""
    rows = []
    for meta_path in sorted(POLICIES.glob("*/*/metadata.json")):
        meta = json.loads(meta_path.read_text())
        for key in EVALUATIONS:
            ev = meta.get(key)
            if ev:
                rows.append({"env_id": meta_path.parent.parent.name,
                             "name": meta_path.parent.name, "key": key, "evaluation": ev,
                             "metadata": meta})
    return rows


def _randomised(meta: dict) -> bool:
    """Whether the policy was trained under per-episode randomisation (its metadata's scene)."""
    from agents.rl.artefacts.policy_files import policy_scene

    return bool(getattr(policy_scene(meta), "randomised", False))


def shipped_table() -> str:
    lines = ["| env id | policy | evaluation | targets (seed) | within ±50 µm [95 % Wilson] | "
             "median \\|error\\| | trained |", "|---|---|---|---|---|---|---|"]
    for r in shipped_rows():
        ev, meta = r["evaluation"], r["metadata"]
        n, rate = ev["n_targets"], ev["success_rate_50um"]
        lo, hi = wilson(round(rate * n), n)
        med = ev.get("median_abs_error_m", ev.get("median_error_m"))
        randomised = ev.get("config") == "trained" and _randomised(meta)
        config = "under its training randomisation" if randomised else EVALUATIONS[r["key"]]
        trained = (f"DAgger, {len(meta['rounds'])} rounds, {meta['wall_time_s'] / 60:.1f} min"
                   if meta.get("trained_by") == "dagger" else
                   f"{meta['steps'] / 1e6:.1f} M steps, {meta['wall_time_s'] / 60:.1f} min")
        lines.append(f"| {r['env_id']} | `{r['name']}` | {config} | {n:,} ({ev['seed']}) | "
                     f"{100 * rate:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] | {_um(med)} | "
                     f"{trained} |")
    lines.append("")
    lines.append("Recorded by `microconveyor record` into each policy's `metadata.json`; "
                 "reproduce one with `microconveyor evaluate --env ID --policy "
                 "agents/policies/ID/NAME --targets N --seed S`.")
    return "\n".join(lines)


# stored `microconveyor seeds` outputs: file -> (env id, recipe, how the seeds were trained)
SEED_RUNS = {
    "ppo_seeds.json": ("MicroConveyor-v0", "PPO, `configs/ppo.yml`", "14.5-min wall budget"),
    "ppo_v1_seeds.json": ("MicroConveyor-v1", "PPO, `configs/ppo.yml`", "6.0 M steps"),
    "ppo_v1_ten_seeds.json": ("MicroConveyor-v1", "PPO, `configs/ppo.yml`",
                              "6.0 M steps, another CPU (AVX-512)"),
    "ppo_v1_refined_ten_seeds.json": ("MicroConveyor-v1", "PPO + `refine`",
                                      "6.0 M steps, then `refine`, another CPU (AVX-512)"),
    "ppo_v1_10M_seeds.json": ("MicroConveyor-v1", "PPO, `configs/ppo.yml`",
                              "10.0 M steps, another CPU (AVX-512)"),
}


def seeds_table() -> str:
    lines = ["| env id | recipe | trained | seeds | within ±50 µm per seed | IQM [95 % bootstrap] "
             "| median \\|error\\| IQM |", "|---|---|---|---|---|---|---|"]
    for name, (env_id, recipe, how) in SEED_RUNS.items():
        d = json.loads((RESULTS / name).read_text())
        s, med = d["success_rate_50um"], d["median_abs_error_m"]
        per = " / ".join(f"{100 * v:.0f}" for v in s["per_seed"])
        lines.append(f"| {env_id} | {recipe} | {how} | {len(s['per_seed'])} | {per} % | "
                     f"{100 * s['iqm']:.1f} % [{100 * s['ci95'][0]:.1f}, {100 * s['ci95'][1]:.1f}] | "
                     f"{_um(med['iqm'])} |")
    lines.append("")
    lines.append("Final checkpoints, each on the 100 targets `train` monitors (target seed 12345, "
                 "tolerance ±50 µm); IQM = 25 %-trimmed mean over seeds, 95 % percentile "
                 "bootstrap over seeds (`microconveyor seeds RUN ... --json`, stored in "
                 "`docs/figures/<file>`: " + ", ".join(f"`{n}`" for n in SEED_RUNS) + ").")
    return "\n".join(lines)


COMPARE_NAMES = {"ppo": "the shipped `ppo`", "ppo_randomised": "the shipped `ppo_randomised`",
                 "mpc": "MPC (re-plans after every firing)", "mpc_ppo": "MPC seeded by `ppo`",
                 "mpc_robust": "robust adaptive MPC", "random": "random actions",
                 "fixed_schedule": "a fixed schedule (950 Hz, 200 µm, no delay)",
                 "de": "DE per target (open loop)", "cmaes": "CMA-ES per target (open loop)",
                 "mpc_identified": "one-step model-based control, friction identified online",
                 "mpc_nominal": "one-step model-based control, nominal model",
                 "mpc_oracle": "reference: the same, knowing each episode's friction and mass",
                 "dagger": "the shipped policy `dagger`"}


def compare_label(data: dict, row: dict) -> str:
    """How the compare table names a row: an MPC seeded by a policy's plan after that policy's
    folder (``prior``: MPC seeded by `ppo_refined`), a policy's row after its folder (the
    shipped `ppo_refined`; the policy `NAME` outside ``agents/policies``), the others by
    :data:`COMPARE_NAMES`."""
    name = row["method"]
    if row.get("prior"):
        what = "robust adaptive MPC" if name == "mpc_robust" else "MPC"
        return f"{what} seeded by `{Path(row['prior']).name}`"
    policy = row.get("policy")
    if policy is None and "train_steps" in row:   # a row without its folder: the result's
        policy = (data.get("randomised_policy") if name == "ppo_randomised" else
                  data.get("policy") if row is data["rows"][0] else None)
    if policy and "train_steps" in row:
        folder = Path(policy)
        if folder.parent.parent.name == "policies":
            return f"the shipped `{folder.name}`"
        return f"the policy `{folder.name}`" + (", trained with randomisation"
                                                if name == "ppo_randomised" else "")
    return COMPARE_NAMES.get(name, name)


def compare_table(data: dict, level: tuple[float, float] = (3e-3, 0.05)) -> str:
    """Rows of a stored ``microconveyor compare --json``: nominal success, error and placement
    time, success at one perturbation ``level`` (σ, r) of the ``combined`` axis, compute per
    target."""
    tol = data["tolerance_m"]
    lines = [f"| method | nominal: within ±{tol * 1e6:.0f} µm [95 % Wilson] | median \\|error\\| | "
             "placement time | "
             f"σ = {level[0]:g}, r = {100 * level[1]:g} %: within ±{tol * 1e6:.0f} µm (detached) "
             "| compute per target |", "|---|---|---|---|---|---|"]
    for row in data["rows"]:
        name = row["method"]
        key = f"{name}_{row['budget']}_plan" if "budget" in row else name
        pert = [x for x in data["perturbation"].get(key, {}).get("combined", [])
                if (x["action_noise"], x["spread"]) == level]
        n = row["n_targets"]
        lo, hi = wilson(round(row["success_rate"] * n), n)
        label = compare_label(data, row) + (f", {row['budget']:,} episodes"
                                            if "budget" in row else "")
        at = (f"{100 * pert[0]['success_rate']:.0f} % ({100 * pert[0]['detach_rate']:.0f} %)"
              if pert else "–")
        med = row.get("median_abs_error_m")
        times = _times(row.get("median_placement_time_s", row.get("median_travel_time_s")),
                       row.get("p90_placement_time_s"))
        lines.append(f"| {label} | {100 * row['success_rate']:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}] "
                     f"| {_um(med) if med is not None else '–'} | {times} | {at} | "
                     f"{_ms(row['wall_s_per_target'])} |")
    percentile = all("p90_placement_time_s" in row for row in data["rows"])
    lines.append("")
    lines.append(f"{data['env_id']}, {len(data['targets_m'])} targets drawn with seed "
                 f"{data['seed']} over the env's range; r: friction and mass factors uniform in "
                 "[1 − r, 1 + r] per episode; one episode per target and level; placement time: "
                 "the simulated time until the part rests, "
                 + ("median / 90th percentile" if percentile else "median")
                 + " over the parts at rest.")
    return "\n".join(lines)


def plane_table(data: dict) -> str:
    import numpy as np

    tol = data["tolerance_m"]
    lines = ["| method | within ±50 µm (Euclidean) | median error | compute per target |",
             "|---|---|---|---|"]
    ppo = data["ppo"]
    lines.append(f"| the shipped `ppo` | {100 * ppo['success_rate_50um']:.0f} % | "
                 f"{_um(ppo['median_error_m'])} | ~{ppo['mean_firings']:.0f} forward passes |")
    for budget, de in data["de"].items():
        err = np.asarray(de["error_m"], float)
        lines.append(f"| DE per target, {int(budget):,} episodes | "
                     f"{100 * float(np.mean(err <= tol)):.0f} % | {_um(float(np.median(err)))} | "
                     f"{int(budget):,} simulated episodes |")
    t = data["targets"]
    lines.append("")
    lines.append(f"MicroConveyor2D-v0, {t['n']} targets (seed {t['seed']}) on the grid's "
                 f"2 × 2 mm box, success at rest within ±{tol * 1e6:.0f} µm; "
                 f"`{data['command']}` (stored in `docs/figures/plane_v0_errors.json`).")
    return "\n".join(lines)


def threads_table(data: dict) -> str:
    lines = ["| torch threads | steps per second (each repeat) |", "|---|---|"]
    for k, v in data["steps_per_s"].items():
        lines.append(f"| {k} | {' / '.join(f'{x:.1f}' for x in v)} |")
    lines.append("")
    lines.append(f"{data['algo']} on {data['env_id']}, {data['steps']:,} steps per run, the "
                 f"settings alternated in one process: one thread is {data['speedup_1_thread']:.1f}× "
                 f"as fast. `{data['provenance']['command']}` "
                 "(stored in `docs/figures/sac_threads.json`).")
    return "\n".join(lines)


def positioner_sizing_table(data: dict) -> str:
    """The positioner's spacing study (``scripts/positioner_sizing.py``)."""
    lines = ["| spacing | actuators | nominal | σ = 3e-3, r = 5 %, model knows the factors | "
             "σ = 3e-3, r = 5 %, nominal model |", "|---|---|---|---|---|"]
    by: dict = {}
    for r in data["rows"]:
        by.setdefault((r["spacing_m"], r["n_actuators"]), {})[r["case"]] = r
    for (sp, n), cases in by.items():
        cells = [f"{100 * c['success_rate']:.0f} % ({_um(c['median_abs_error_m'])}, "
                 f"{c['mean_firings']:.1f} firings)" for c in cases.values()]
        lines.append(f"| {sp * 1e3:.2f} mm | {n} | " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(f"Share of {data['targets']} targets (uniform over 0.5–10 mm, seed "
                 f"{data['target_seed']}) at rest within ±50 µm after at most 24 firings of the "
                 "one-step model-based controller, in brackets the median error and the mean "
                 f"firings; the array spans 0–{data['span_m'] * 1e3:g} mm. `{data['command']}` "
                 f"({data['date']}, stored in `docs/figures/positioner_sizing.json`).")
    return "\n".join(lines)


def positioner_seeds_table(data: dict) -> str:
    """Positioner policies of several training seeds (``scripts/positioner_policies.py``)."""
    lines = ["| seed | trained | σ = 3e-3, r = 5 %: within ±50 µm | within ±10 µm | median "
             "\\|error\\| | detached | nominal: within ±50 µm | median \\|error\\| | "
             "detached |", "|---|---|---|---|---|---|---|---|---|"]
    for r in data["runs"]:
        p, q = r["perturbed"], r["nominal"]
        lines.append(f"| {r['seed']} | {r['trained_by']}, {r['train_wall_time_s'] / 60:.1f} min | "
                     f"{100 * p['success_rate_50um']:.1f} % | {100 * p['success_rate_10um']:.1f} % "
                     f"| {_um(p['median_abs_error_m'])} | {100 * p['detach_rate']:.1f} % | "
                     f"{100 * q['success_rate_50um']:.1f} % | {_um(q['median_abs_error_m'])} | "
                     f"{100 * q['detach_rate']:.1f} % |")
    iq = data["iqm"]

    def ci(c: str, m: str, scale: float = 100.0, fmt: str = "{:.1f} %") -> str:
        d = iq[c][m]
        return (fmt.format(scale * d["iqm"]) + " [" + fmt.format(scale * d["ci95"][0]) + ", "
                + fmt.format(scale * d["ci95"][1]) + "]")

    um = "{:.1f} µm"
    lines.append(f"| IQM [95 % bootstrap] | | {ci('perturbed', 'success_rate_50um')} | "
                 f"{ci('perturbed', 'success_rate_10um')} | "
                 f"{ci('perturbed', 'median_abs_error_m', 1e6, um)} | "
                 f"{ci('perturbed', 'detach_rate')} | {ci('nominal', 'success_rate_50um')} | "
                 f"{ci('nominal', 'median_abs_error_m', 1e6, um)} | "
                 f"{ci('nominal', 'detach_rate')} |")
    lines.append("")
    lines.append(f"Final policies, {data['n_targets']:,} held-out targets (uniform over 0.5–10 "
                 f"mm, seed {data['target_seed']}), one episode each; IQM over seeds with its "
                 f"95 % percentile bootstrap interval. `{data['command']}` ({data['date']}, "
                 "stored in `docs/figures/positioner_seeds.json`).")
    return "\n".join(lines)


def imitate_table(data: dict, stored: str = "imitate_v1_seeds.json") -> str:
    """Training seeds of ``microconveyor imitate`` with their wall time on one core
    (``benchmarks/imitate_wall_time.py``; stored in ``docs/figures/<stored>``)."""
    crit = data["criterion"]
    lines = ["| seed | wall time | CPU time | within ±50 µm | median \\|error\\| | 90th pct. "
             "\\|error\\| | detached | meets the criterion |", "|---|---|---|---|---|---|---|---|"]
    for r in data["seeds"]:
        lines.append(f"| {r['seed']} | {r['wall_time_s']:.0f} s | {r['cpu_time_s']:.0f} s | "
                     f"{100 * r['success_rate']:.1f} % | {_um(r['median_abs_error_m'])} | "
                     f"{_um(r['p90_abs_error_m'])} | {100 * r['detach_rate']:.1f} % | "
                     f"{'yes' if r['meets_criterion'] else 'no'} |")
    sm = data["summary"]
    iq = sm["success_iqm"]
    w = sm["worst_seed"]
    lines.append("")
    lines.append(f"{sm['meeting_criterion']} of {sm['seeds']} seeds meet v1's criterion (≥ "
                 f"{100 * crit['success_rate']:.0f} % within ±50 µm and a median ≤ "
                 f"{_um(crit['median_abs_error_m'])}); success IQM **{100 * iq['iqm']:.1f} %** "
                 f"[95 % bootstrap {100 * iq['ci95'][0]:.1f}, {100 * iq['ci95'][1]:.1f}]; worst "
                 f"seed {w['seed']}: {100 * w['success_rate']:.1f} %, median "
                 f"{_um(w['median_abs_error_m'])}. Wall time of the command, median "
                 f"**{sm['median_wall_time_s']:.0f} s**, slowest {sm['slowest_wall_time_s']:.0f} s "
                 f"(seed {sm['slowest_seed']}). A policy acts in {_ms(data['act_time_s'])} per "
                 "observation (seed 0's, one observation at a time, fixed-order float64 "
                 f"inference). Final policies on {data['targets']:,} held-out "
                 f"targets (uniform over 0.5–10 mm, seed {data['eval_seed']}), one episode each; "
                 f"each training pinned to one core, "
                 f"{'side by side, one per core' if data['machine'].get('parallel_cpus') else 'one after the other'}"
                 f" ({data['note']}). `{_command(data)}` ({data['date']}, stored in "
                 f"`docs/figures/{stored}`).")
    return "\n".join(lines)


def code_paths_table(data: dict) -> str:
    """The same seeds trained on two of torch's CPU code paths
    (``benchmarks/imitate_wall_time.py --compare-with``)."""
    m = data["machine"]
    flags = ", ".join(f"{k}={v}" for k, v in m["env"].items())
    here = (f"torch without SIMD, MKL on its baseline path ({flags})"
            if m["torch_cpu_capability"] == "DEFAULT" else f"{m['torch_cpu_capability']} ({flags})")
    lines = [f"| seed | machine default (AVX2): within ±50 µm, median | {here}: within ±50 µm, "
             "median | same side of the criterion | identical episodes |", "|---|---|---|---|---|"]
    for r in data["seeds"]:
        o = r["other_path"]
        lines.append(f"| {r['seed']} | {100 * o['success_rate']:.1f} %, "
                     f"{_um(o['median_abs_error_m'])} | {100 * r['success_rate']:.1f} %, "
                     f"{_um(r['median_abs_error_m'])} | "
                     f"{'yes' if r['same_side_of_criterion'] else 'no'} "
                     f"| {'yes' if o['same_episodes'] else 'no'} (largest difference "
                     f"{_small_m(o['max_error_difference_m'])}) |")
    lines.append("")
    lines.append(f"The same command and seeds, {data['targets']:,} held-out targets (seed "
                 f"{data['eval_seed']}); {data['note']}. `{_command(data)}` ({data['date']}, "
                 "stored in "
                 "`docs/figures/imitate_v1_code_paths.json`).")
    return "\n".join(lines)


# the parts of a training, as benchmarks/train_time_breakdown.py times them
BREAKDOWN = (("env stepping", ("env_compiled", "env_adapter", "env_monitor", "env_normalize")),
             ("policy inference", ("inference",)),
             ("rollout bookkeeping", ("buffer", "callbacks", "rollout_loop")),
             ("gradient updates", ("updates",)), ("logging", ("logging",)),
             ("periodic evaluation", ("evaluation",)), ("checkpoints", ("checkpoints",)),
             ("setup", ("setup",)), ("refinement", ("refinement",)))


def breakdown_table(data: dict) -> str:
    """Where a v1 PPO training's time goes (``benchmarks/train_time_breakdown.py``)."""
    run, full = data["run"], data["full_recipe_estimate"]
    lines = ["| part | measured run: wall | CPU | share of CPU | 6 M-step recipe (estimate): "
             "wall | share |", "|---|---|---|---|---|---|"]
    cpu_total = sum(run["parts_cpu_s"].values()) - run["parts_cpu_s"].get("env_step", 0) \
        - run["parts_cpu_s"].get("bookkeeping", 0)
    wall_total = full["total_s"]
    for name, keys in BREAKDOWN:
        w = sum(run["parts_s"].get(k, 0.0) for k in keys)
        c = sum(run["parts_cpu_s"].get(k, 0.0) for k in keys)
        fw = sum(full["parts_s"].get(k, 0.0) for k in keys)
        lines.append(f"| {name} | {w:.1f} s | {c:.1f} s | {100 * c / cpu_total:.1f} % | "
                     f"{fw / 60:.1f} min | {100 * fw / wall_total:.1f} % |")
    m = data["machine"]
    lines.append("")
    lines.append(f"The measured run: {run['steps']:,} steps of the recipe and "
                 f"{run['refine_rounds']} refinement round; the estimate scales it to "
                 f"{full['steps']:,} steps and 8 rounds (the script's docstring). One core "
                 f"(affinity {m['cpu_affinity']}), torch {m['torch']} on 1 thread; load average "
                 f"{m['load_average_before'][0]:.1f} before and {m['load_average_after'][0]:.1f} "
                 "after: on a busy machine the seconds are upper bounds and the CPU shares are "
                 f"the measure. `{data['command']}` ({data['recorded_utc']}, stored in "
                 "`docs/figures/train_time_breakdown.json`).")
    return "\n".join(lines)


def firing_maps_table(data: dict) -> str:
    """Each scene's firing map against the full model (``microconveyor firing-map --json``)."""
    lines = ["| env id: map | strokes tabulated (build) | trusted | error median / 99th pct / "
             "max | largest relative | trusted that detach | per query : per full stroke |",
             "|---|---|---|---|---|---|---|"]
    for r in data["maps"]:
        rows = [("at rest" if r["from_rest"] else "end of stroke", r)]
        if r.get("at_rest"):
            rows.append(("then at rest", {**r, **r["at_rest"]}))
        for what, e in rows:
            lines.append(
                f"| {r['env_id']}: {'from rest' if r['from_rest'] else 'moving parts'}, {what} "
                f"| {r['nodes']:,} ({r['build_s']:.0f} s) | {100 * e['trusted_share']:.0f} % "
                f"| {_um(e['error_median_m'])} / {_um(e['error_p99_m'])} / "
                f"{_um(e['error_max_m'])} | {100 * e['relative_error_max']:.2f} % "
                f"| {e['misclassified_detachments']} | {e['map_query_s'] * 1e6:.2f} µs : "
                f"{e['full_stroke_s'] * 1e6:.1f} µs |")
    lines.append("")
    lines.append(f"{data['samples']:,} held-out strokes per map, drawn uniformly over its grid "
                 f"(log-uniformly in frequency) with seed {data['seed']}; one thread. "
                 f"`{data['command']}` ({data['recorded_utc']}, stored in "
                 "`docs/figures/firing_maps.json`).")
    return "\n".join(lines)


PLANNER_NAMES = {"v1_mpc_de": "MicroConveyor-v1: MPC seeded by `ppo_refined`, DE 300 + 100 "
                              "per re-plan",
                 "v1_mpc_newton": "MicroConveyor-v1: MPC seeded by `ppo_refined`, Gauss-Newton "
                                  "re-plan",
                 "positioner_model": "MicroPositioner-v0: one-step control, identified, "
                                     "every candidate on the full model",
                 "positioner_map": "MicroPositioner-v0: one-step control, identified, ranked "
                                   "on the firing map"}


def _detail_times(level: dict) -> str:
    """:func:`_episode_times` of a stored level's ``episodes_detail``."""
    detail = level.get("episodes_detail", {})
    return _episode_times(detail.get("sim_time_s"), detail.get("outcome", []))


def planner_speed_table(data: dict) -> str:
    """MPC per target before and after the fast planners (``scripts/planner_speed.py``)."""
    lines = ["| method | code | nominal: success, median \\|error\\| | perturbed: success, "
             "median \\|error\\| (detached) | placement time: nominal; perturbed | compute per "
             "target: nominal / perturbed | model episodes per target |",
             "|---|---|---|---|---|---|---|"]
    for key, levels in data["methods"].items():
        code, method = key.split("/")
        nom = levels["nominal"]
        per = levels.get("noise") or levels["perturbed"]
        lines.append(
            f"| {PLANNER_NAMES[method]} | {code} ({data['revisions'][code]}) "
            f"| {100 * nom['success_rate']:.0f} %, {_um(nom['median_abs_error_m'])} "
            f"| {100 * per['success_rate']:.0f} %, {_um(per['median_abs_error_m'])} "
            f"({100 * per['detach_rate']:.0f} %) | {_detail_times(nom)}; {_detail_times(per)} "
            f"| {_ms(nom['wall_s_per_target_mean'])} / "
            f"{_ms(per['wall_s_per_target_mean'])} | {nom['model_episodes_mean']:,.0f} |")
    loads = data["load_average_1_5_15"]
    lines.append("")
    lines.append(
        f"MicroConveyor-v1: {data['v1_targets_per_distance']} targets at each of "
        f"{', '.join(f'{d * 1e3:.0f}' for d in data['v1_distances_m'])} mm (the answer "
        f"table's), nominal and under execution noise σ = 3e-3 ({data['noise_seeds']} noise "
        f"seeds per target); MicroPositioner-v0: {data['positioner_targets']} targets (seed 0), "
        "nominal and at σ = 3e-3, r = 5 %. Placement time: the simulated time until the part "
        "rests, median / 90th percentile over the parts at rest. "
        "The same episodes for every method; each method in a "
        f"process of its own on one thread, alternating; load average "
        f"{min(v[0] for v in loads):.1f}-{max(v[0] for v in loads):.1f} during the run. "
        f"`{data['command']}` ({data['date']}, stored in `docs/figures/planner_speed.json`).")
    return "\n".join(lines)


DAGGER_PARTS = (("expert_setup", "expert construction"), ("expert", "expert labelling"),
                ("env", "env stepping"), ("student_act", "student acting"),
                ("fit", "fitting the network"), ("other", "setup and other"))


def dagger_breakdown_table(runs: list[dict]) -> str:
    """CPU time per part of each DAgger recipe (``benchmarks/dagger_breakdown.py``), one column
    per env id."""
    lines = ["| part | " + " | ".join(f"{r['env_id']}: CPU, share" for r in runs) + " |",
             "|---|" + "---|" * len(runs)]
    for key, label in DAGGER_PARTS:
        cells = [f"{r['parts'][key]['cpu_s']:.1f} s, "
                 f"{100 * r['parts'][key]['cpu_s'] / r['total_cpu_s']:.0f} %" for r in runs]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines.append("| **total** (wall) | " + " | ".join(
        f"**{r['total_cpu_s']:.0f} s** ({r['total_wall_s']:.0f} s)" for r in runs) + " |")
    lines.append("")
    lines.append("; ".join(
        f"{r['env_id']}: seed {r['seed']}, {r['rounds']} rounds x {r['episodes_per_round']} "
        f"episodes, last round {100 * r['final_round_success_rate']:.0f} % within tolerance, "
        f"load average {r['load_average_before'][0]:.1f} before and "
        f"{r['load_average_after'][0]:.1f} after, `{r['command']}` ({r['date']})"
        for r in runs) + ". One pinned core shared with other jobs: the wall seconds are upper "
        "bounds, the CPU shares the measure (stored in `docs/figures/dagger_breakdown_*.json`).")
    return "\n".join(lines)


FRONTIER_SCENES = {"line": "MicroConveyor-v1", "positioner": "MicroPositioner-v0",
                   "plane": "MicroConveyor2D-v1"}
FRONTIER_HOLDS = 0.9   # the share within the request a method must hold to answer it


def frontier_caption(data: dict, scene: str) -> str:
    """Where a stored frontier's rows come from: targets, levels, the time bound, the command."""
    levels = "; ".join(f"{name}: σ = {lv['action_noise']:g}, r = {100 * lv['spread']:g} %"
                       for name, lv in data.get("levels", {}).items())
    bound = data.get("time_bound_s")
    told = (f" The physical lower bound on the placement time of the median target "
            f"(`agents/planning/bounds.py`): {_ms(bound)}." if bound else "")
    return (f"{data['env_id']}; held-out targets drawn with seed {data.get('target_seed')} (the "
            f"number per row in its column); {levels}. A request is the env's `tolerance` (the "
            "episode ends once the part rests within it); placement time: the simulated time "
            "until the part rests, median and 90th percentile over the parts at rest; wall per "
            f"target on the machine of [Provenance](#provenance).{told} Reproduce: "
            f"`nice python scripts/frontier.py --env {data['env_id']} --out "
            f"docs/figures/frontier_{scene}.json --plot docs/figures/frontier_{scene}.png`.")


def frontier_scene_table(data: dict, scene: str) -> str:
    """A stored frontier (``scripts/frontier.py``) as a table, then its caption."""
    from agents.experiments.frontier import frontier_table

    return frontier_table(data) + "\n" + frontier_caption(data, scene)


def frontier_answer(datas: dict[str, dict]) -> str:
    """Per scene, level and request (±50 and ±10 µm): the fastest method (least median
    placement time) that holds at least :data:`FRONTIER_HOLDS` of its parts within the request,
    from the stored frontiers."""
    lines = ["| env id | level | request | fastest method holding ≥ 90 % | within the request | "
             "placement time (median / p90) | detached |", "|---|---|---|---|---|---|---|"]
    for data in datas.values():
        for level in data.get("levels", {}):
            for um in (50, 10):
                rows = [r for r in data["rows"] if r["level"] == level
                        and round(r["request_tolerance_m"] * 1e6) == um
                        and r.get("median_placement_time_s") is not None]
                held = [r for r in rows if r[f"success_rate_{um}um"] >= FRONTIER_HOLDS]
                if held:
                    r = min(held, key=lambda r: r["median_placement_time_s"])
                    cells = (f"`{r['method']}`", f"{100 * r[f'success_rate_{um}um']:.0f} %",
                             _times(r["median_placement_time_s"], r["p90_placement_time_s"]),
                             f"{100 * r['detach_rate']:.0f} %")
                elif rows:
                    r = max(rows, key=lambda r: r[f"success_rate_{um}um"])
                    cells = (f"none (best: `{r['method']}`)",
                             f"{100 * r[f'success_rate_{um}um']:.0f} %",
                             _times(r["median_placement_time_s"], r["p90_placement_time_s"]),
                             f"{100 * r['detach_rate']:.0f} %")
                else:
                    continue
                lines.append(f"| {data['env_id']} | {level} | ±{um} µm | " + " | ".join(cells)
                             + " |")
    return "\n".join(lines) + ("\n\nFrom the stored frontiers `docs/figures/frontier_*.json` "
                               "(`scripts/frontier.py`); every row, method and chart: "
                               "docs/results.md, \"Placement time against precision\".")


def v1_fast_table(data: dict) -> str:
    """MicroConveyor-v1's recipe from the simulator alone, per training seed, with placement
    times and the time over the lower bound (``docs/figures/v1_fast.json``)."""
    lines = ["| seed | level | within ±50 / 20 / 10 / 5 µm | detached | placement time "
             "(median / p90) | time over the bound, targets beyond 8 mm (max) | training wall "
             "(CPU) |", "|---|---|---|---|---|---|---|"]
    levels = {"nominal": "nominal", "noise_3e-3_factors_5pct": "σ = 3e-3, r = 5 %"}
    seeds = data["dagger_seeds"]["seeds"]
    for seed, run in seeds.items():
        for key, name in levels.items():
            f = run[key]
            within = " / ".join(f"{100 * f[f'success_rate_{k}um']:.1f}" for k in (50, 20, 10, 5))
            lines.append(f"| {seed} | {name} | {within} % | {100 * f['detach_rate']:.1f} % | "
                         f"{_times(f['median_placement_time_s'], f['p90_placement_time_s'])} | "
                         f"{f['time_over_bound_max_targets_over_8mm']:.2f} | "
                         f"{run['wall_time_s']:.0f} s ({run['user_cpu_time_s']:.0f} s) |")
    summ = data["dagger_seeds"]["summary"]["nominal"]
    b = data["bound"]
    return "\n".join(lines) + (
        f"\n\nIQM over the seeds, nominal: {100 * summ['success_rate_50um']['iqm']:.1f} % within "
        f"±50 µm, median placement time {_ms(summ['median_placement_time_s']['iqm'])}. "
        f"1,000 held-out targets (seed 1) per row. The bound: a_f = {b['a_f_m_s2']:.2f} m/s², "
        f"X = {b['X_m'] * 1e3:.1f} mm, {_ms(b['bound_s_at_m']['10 mm'])} at 10 mm; "
        f"{b['check']['episodes_played_total']:,} nominal episodes played, none faster than it "
        f"(smallest time over bound {b['check']['smallest_time_over_bound_seen']:.3f}). "
        f"Measured {data['date']} ({data['machine']['cpu_count']} cores, shared). Train: "
        "`microconveyor imitate --env MicroConveyor-v1 --seed S` (S = 0, 1, 2, one at a time).")


def request_table(data: dict) -> str:
    """The request-conditioned DAgger policies per scene, level and request: IQM over the
    training seeds with each seed's share within the request (``docs/figures/request_seeds.json``)."""
    lines = ["| env id | level | request | within the request: IQM (per seed) | within ±50 / 20 / "
             "10 / 5 µm (IQM) | detached | placement time (median / p90, IQM) | training wall "
             "per seed |", "|---|---|---|---|---|---|---|---|"]
    for env_id, scene in data["scenes"].items():
        walls = ", ".join(f"{run['train_wall_time_s']:.0f} s" for run in scene["seeds"].values())
        for key, f in scene["iqm"].items():
            level, um = key.split("/")
            own = f[f"success_rate_{um}um"]
            per_seed = ", ".join(f"{100 * v:.1f}" for v in own["per_seed"])
            within = " / ".join(f"{100 * f[f'success_rate_{k}um']['iqm']:.1f}"
                                for k in (50, 20, 10, 5))
            lines.append(f"| {env_id} | {level} | ±{um} µm | {100 * own['iqm']:.1f} % "
                         f"({per_seed}) | {within} % | {100 * f['detach_rate']['iqm']:.1f} % | "
                         f"{_times(f['median_placement_time_s']['iqm'], f['p90_placement_time_s']['iqm'])}"
                         f" | {walls} |")
    commands = "; ".join(f"`{next(iter(sc['seeds'].values()))['train_command'].split(' --out')[0]}`"
                         for sc in data["scenes"].values())
    return "\n".join(lines) + (
        "\n\nOne network per training seed (0, 1, 2) serves every request; 1,000 held-out targets "
        "(seed 1) per row, `randomised`: the recipe's σ = 3e-3 with ±5 % friction and mass. "
        f"Measured {data['date_utc']} UTC ({data['machine']['cpu_count']} shared cores; each "
        f"training beside other jobs). Train (seed 0 shown): {commands}.")


def generators() -> dict:
    """Region name -> a function returning its text."""
    def load(name: str) -> dict:
        return json.loads((RESULTS / name).read_text())

    return {"answer": lambda: answer_table(load("answer_table.json")),
            "noise": lambda: noise_table(load("answer_table.json")),
            "shipped": shipped_table,
            "seeds": seeds_table,
            "compare": lambda: compare_table(load("compare_v1_mpc_ppo.json")),
            "plane": lambda: plane_table(load("plane_v0_errors.json")),
            "threads": lambda: threads_table(load("sac_threads.json")),
            "positioner_compare": lambda: compare_table(load("compare_positioner.json")),
            "positioner_sizing": lambda: positioner_sizing_table(load("positioner_sizing.json")),
            "positioner_seeds": lambda: positioner_seeds_table(load("positioner_seeds.json")),
            "breakdown": lambda: breakdown_table(load("train_time_breakdown.json")),
            "imitate_v1": lambda: imitate_table(load("imitate_v1_seeds.json")),
            "imitate_v1_nothing": lambda: imitate_table(load("imitate_v1_nothing_seeds.json"),
                                                        "imitate_v1_nothing_seeds.json"),
            "imitate_v1_paths": lambda: code_paths_table(load("imitate_v1_code_paths.json")),
            "firing_maps": lambda: firing_maps_table(load("firing_maps.json")),
            "planner_speed": lambda: planner_speed_table(load("planner_speed.json")),
            "frontier_line": lambda: frontier_scene_table(load("frontier_line.json"), "line"),
            "frontier_positioner": lambda: frontier_scene_table(load("frontier_positioner.json"),
                                                                "positioner"),
            "frontier_plane": lambda: frontier_scene_table(load("frontier_plane.json"), "plane"),
            "frontier_answer": lambda: frontier_answer(
                {k: load(f"frontier_{k}.json") for k in FRONTIER_SCENES}),
            "v1_fast": lambda: v1_fast_table(load("v1_fast.json")),
            "request_seeds": lambda: request_table(load("request_seeds.json")),
            "dagger_breakdown": lambda: dagger_breakdown_table(
                [json.loads(f.read_text())
                 for f in sorted(RESULTS.glob("dagger_breakdown_*.json"))])}


def render(text: str, gens: dict, cache: dict) -> str:
    """``text`` with every region rewritten (an unknown region name is an error)."""
    def sub(m: re.Match) -> str:
        name = m["name"]
        if name not in gens:
            raise KeyError(f"no generator for region {name!r}; known: {sorted(gens)}")
        if name not in cache:
            cache[name] = gens[name]()
        return f"{m.group(1)}{cache[name]}\n{m.group(4)}"

    return REGION.sub(sub, text)


def regions(text: str) -> list[str]:
    return [m["name"] for m in REGION.finditer(text)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 if a region differs")
    ap.add_argument("--root", type=Path, default=ROOT,
                    help="the folder whose README.md and docs/*.md are rewritten (default: this "
                         "repository's); the stored results are always this repository's")
    args = ap.parse_args(argv)
    gens, stale = generators(), []
    cache: dict[str, str] = {}
    pages = PAGES if args.root == ROOT else (args.root / "README.md",
                                             *sorted((args.root / "docs").glob("*.md")))
    for page in pages:
        text = page.read_text()
        new = render(text, gens, cache)
        if new != text:
            stale.append(f"{page.relative_to(args.root)}: {', '.join(regions(text))}")
            if not args.check:
                page.write_text(new)
    for s in stale:
        print(("differs: " if args.check else "rewrote: ") + s, file=sys.stderr)
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
