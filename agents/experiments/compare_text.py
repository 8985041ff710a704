"""The comparison's result (:func:`.compare.compare`) as plain text: one line per method and
budget (success, error, placement time, compute), the MPCs' compute, and success under every
perturbation level (the full grid as a matrix per method). Units people read: µm, ms, %.
"""
from __future__ import annotations

from pathlib import Path


def placement_cells(row: dict) -> str:
    """A row's placement time (median, 90th percentile) as two 9-wide cells in ms, blank where
    no part rested or the row holds no such figure (a comparison stored before it had the 90th
    percentile gives its median alone)."""
    med = row.get("median_placement_time_s", row.get("median_travel_time_s"))
    p90 = row.get("p90_placement_time_s")
    return "".join(f"{'' if t is None else f'{1e3 * t:.1f} ms':>9}" for t in (med, p90))


def summary_table(result: dict) -> str:
    """The comparison as a plain-text table (one line per method and budget): success, median
    |error|, the placement time of the parts that rested (median ``time`` and 90th percentile),
    compute per target."""
    if "plan_firings" in result:
        return positioner_table(result)
    head = (f"{'method':<16}{'budget':>7}{'success':>9}{'median |err|':>14}{'time':>9}"
            f"{'p90 time':>9}{'wall/target':>13}{'episodes':>10}{'crossover N':>13}")
    lines = [head, "-" * len(head)]
    for r in result["rows"]:
        cross = r.get("crossover_targets")
        lines.append(
            f"{r['method']:<16}{r.get('budget', ''):>7}{100 * r['success_rate']:>8.0f}%"
            f"{1e6 * r['median_abs_error_m']:>11.1f} µm{placement_cells(r)}"
            f"{1e3 * r['wall_s_per_target']:>10.2f} ms{r['episodes_per_target']:>10.0f}"
            f"{'' if cross is None else f'{cross:.0f}':>13}")
    ppo = result["rows"][0]
    lines.append(f"policy {result.get('policy') or ppo['method']}: training "
                 f"{ppo['train_wall_s']:.0f} s, {ppo['train_steps']:,} env steps (firings); "
                 f"amortised over {result['ppo_amortised']['over_targets']} targets: "
                 f"{result['ppo_amortised']['wall_s_per_target']:.2f} s per target")
    for r in result["rows"]:
        if "settings" in r:   # the MPCs
            st = r["settings"]
            extra = (f", {st['noise_copies']} noisy copies at σ={st['assumed_noise']:g}"
                     if st["noise_copies"] > 1 else "")
            extra += ", friction and mass identified online" if st["identify"] else ""
            extra += f", seeded by {Path(r['prior']).name}'s plan" if r.get("prior") else ""
            lines.append(f"{r['method']} ({st['method']}, {st['first_budget']} episodes before "
                         f"the first firing, {st['replan_budget']} per re-plan{extra}): "
                         f"{r['episodes_per_target']:.0f} model episodes and "
                         f"{r['planning_wall_s_per_target']:.2f} s of planning per target "
                         f"({r['wall_s_per_target']:.2f} s wall with {r['workers']} workers)")
    lines += ["", perturbation_text(result)]
    return "\n".join(lines)


def _level_name(row: dict) -> str:
    return f"σ={row['action_noise']:g},r={100 * row['spread']:g}%"


def perturbation_text(result: dict) -> str:
    """Success within the tolerance [%] of every method at every perturbation level, one block
    per axis (levels as σ [action units], r [%]); with PPO seeds, their IQM [95 % CI]."""
    pert = result["perturbation"]
    if not pert:
        return ""
    first = next(iter(pert.values()))
    out = []
    for axis, levels in first.items():
        if axis == "grid":
            out.append(_grid_text(pert))
            continue
        names = [_level_name(r) for r in levels]
        width = max(14, *(len(n) + 1 for n in names))
        out.append(f"success [%] under perturbation, {axis}:")
        out.append(f"{'method':<18}" + "".join(f"{n:>{width}}" for n in names))
        for method, tables in pert.items():
            out.append(f"{method:<18}" + "".join(
                f"{100 * r['success_rate']:>{width}.0f}" for r in tables[axis]))
        seeds = result.get("seeds")
        if seeds:
            cells = [f"{100 * r['iqm']:.0f} [{100 * r['ci95'][0]:.0f},{100 * r['ci95'][1]:.0f}]"
                     for r in seeds["perturbation"][axis]]
            out.append(f"{'PPO seeds IQM':<18}" + "".join(f"{c:>{width}}" for c in cells))
    return "\n".join(out)


def _grid_text(pert: dict) -> str:
    """The full grid: per method, success [%] with σ down and r across."""
    out = ["success [%] under perturbation, full grid (rows: noise σ; columns: model error r):"]
    for method, tables in pert.items():
        grid = tables["grid"]
        sig = sorted({r["action_noise"] for r in grid})
        rr = sorted({r["spread"] for r in grid})
        val = {(r["action_noise"], r["spread"]): r["success_rate"] for r in grid}
        out.append(f"{method:<18}" + "".join(f"{f'r={100 * r:g}%':>9}" for r in rr))
        for x in sig:
            out.append(f"{f'  σ={x:g}':<18}" + "".join(f"{100 * val[(x, r)]:>9.0f}" for r in rr))
    return "\n".join(out)


def _wilson_text(row: dict) -> str:
    from .perturb import wilson

    if "success_ci95" in row:
        lo, hi = row["success_ci95"]
    else:
        n = row["n_targets"]
        lo, hi = wilson(round(row["success_rate"] * n), n)
    return f"{100 * row['success_rate']:.0f}% [{100 * lo:.0f},{100 * hi:.0f}]"


def positioner_table(result: dict) -> str:
    """The positioner's comparison (:func:`.compare.compare` on a positioner id) as text: one line per method
    (success with its 95 % Wilson interval, median |error|, detach rate, compute per target),
    then per method and perturbation level success, median |error| and detach rate; the
    reference row is named as such. The placement time (``time``: median, ``p90 time``) is that
    of the parts that rested."""
    refs = result.get("reference_methods", {})
    head = (f"{'method':<22}{'budget':>7}{'success [95% CI]':>19}{'median |err|':>14}"
            f"{'time':>9}{'p90 time':>9}"
            f"{'detached':>10}{'compute/target':>16}{'model firings':>15}")
    lines = [head, "-" * len(head)]
    for r in result["rows"]:
        ep = r.get("episodes_per_target")
        lines.append(
            f"{r['method']:<22}{r.get('budget', ''):>7}{_wilson_text(r):>19}"
            f"{1e6 * r['median_abs_error_m']:>11.1f} µm{placement_cells(r)}"
            f"{100 * r['detach_rate']:>9.0f}%"
            f"{1e3 * r['wall_s_per_target']:>13.1f} ms"
            f"{'' if ep is None or 'budget' in r else f'{ep:.0f}':>15}")
    for r in result["rows"]:
        if r["method"] in refs:
            lines.append(f"{r['method']}: {refs[r['method']]}")
        if "budget" in r:
            lines.append(f"{r['method']} {r['budget']}: plans of {r['plan_firings']} firings, "
                         f"{r['episodes_per_target']:.0f} model episodes per target")
    lines.append("")
    pert = result["perturbation"]
    for axis in next(iter(pert.values()), {}):
        lines.append(f"under perturbation, {axis} (success [95% CI], median |err| µm, "
                     "detached %):")
        for method, tables in pert.items():
            name = method + (" (reference)" if method in refs else "")
            lines.append(f"  {name}")
            for row in tables[axis]:
                lines.append(f"    {_level_name(row):<18}{_wilson_text(row):>16}"
                             f"{1e6 * row['median_abs_error_m']:>10.1f}"
                             f"{100 * row['detach_rate']:>8.0f}")
    return "\n".join(lines)
