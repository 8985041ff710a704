"""MicroPositioner-v0's DAgger expert ranked on the firing map against the full-model search (a
benchmark script, not a test).

    python benchmarks/positioner_expert.py [--states 3000] [--seed 0] [--grids 41x6,81x11]

Draws resting states (half with the part anywhere on the array and the target anywhere in the
target range, half with the part 10 µm to 2 mm from its target, log-uniform, on either side),
labels them with :class:`agents.mpc.experts.BatchExpert` searching every candidate on the full
model (``search="model"``, the reference) and ranking them on the map (``search="map"``, for
each grid given), and prints JSON: the wall time per state on one thread, the full-model
firings per state, the share of states where both choose the same firing and where both agree
that a firing helps, and, for the chosen firings fired on the full model: on the states where
the reference's firing lands within the env's tolerance (it can finish there), the landing
error's median, 90th percentile and maximum [µm] and the share within the tolerance; on the
others, the map expert's travel towards the target over the reference's (median, 10th
percentile); everywhere, the difference between the two experts' landings (map minus reference,
percentiles 1 to 99) [µm] and the share of states where the map expert lands within the slack of
the reference. The recipe's expert settings (margin, slack, heavier part); a finer grid's margin
is scaled to cover the same span of the frequency action as the recipe's.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from microconveyor_env.envs.positioner.config import PositionerConfig


def states(cfg: PositionerConfig, n: int, seed: int) -> tuple[np.ndarray, ...]:
    """``n`` resting states (x [m], t [s], target [m]) as the module docstring draws them."""
    rng = np.random.default_rng(seed)
    lo, hi = cfg.target_range
    target = rng.uniform(lo, hi, n)
    x_lo, x_hi = -cfg.start_offset, float(cfg.actuator_positions[-1])
    far = rng.uniform(x_lo, x_hi, n)
    near = target + rng.choice([-1.0, 1.0], n) * np.exp(rng.uniform(np.log(10e-6),
                                                                    np.log(2e-3), n))
    x = np.clip(np.where(np.arange(n) < n // 2, far, near), x_lo, x_hi)
    return x, np.zeros(n), target


def label(expert, x, t, target, chunk: int = 64) -> tuple[np.ndarray, np.ndarray, float]:
    acts, ok = np.zeros((len(x), 3), np.float32), np.zeros(len(x), bool)
    expert.act(x[:2], t[:2], target[:2])   # compile and build outside the clock
    t0 = time.perf_counter()
    for lo in range(0, len(x), chunk):
        sl = slice(lo, lo + chunk)
        acts[sl], ok[sl] = expert.act(x[sl], t[sl], target[sl])
    return acts, ok, time.perf_counter() - t0


def main() -> None:
    import torch

    from agents.imitation.dagger import recipe
    from agents.mpc.experts import BatchExpert

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--states", type=int, default=3000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--grids", default="41x6,81x11",
                   help="the map expert's frequencies x strokes, comma-separated")
    p.add_argument("--reference", default=None,
                   help="the full-model search's frequencies x strokes (default: the recipe's)")
    args = p.parse_args()
    torch.set_num_threads(1)
    s = recipe("MicroPositioner-v0")
    cfg = PositionerConfig.from_yaml(None, num_threads=1)
    x, t, target = states(cfg, args.states, args.seed)
    rf, rh = ((int(v) for v in args.reference.split("x")) if args.reference
              else (s.frequencies, s.strokes))

    def margin_of(f: int) -> int:   # the recipe's margin over the same span of the action
        return max(1, round(s.margin * (f - 1) / (s.frequencies - 1)))

    ref = BatchExpert(cfg, rf, rh, margin_of(rf), s.slack_m, s.heavier, search="model")
    ra, rok, rs = label(ref, x, t, target)
    rx, _ = ref.fire(x, t, target, ra.astype(np.float64))
    rerr = np.abs(rx - target)
    fin = rok & (rerr <= cfg.tolerance)   # the reference finishes from these
    gone = np.abs(x - target) - rerr      # its travel towards the target [m]
    rows: dict = {"reference": {
        "grid": f"{rf}x{rh}", "margin": margin_of(rf), "search": "model",
        "ms_per_state": rs / len(x) * 1e3,
        "full_firings_per_state": ref.full_firings / (len(x) + 2),
        "finishing_states": int(fin.sum()),
        "finishing_error_um": [float(np.percentile(rerr[fin], q) * 1e6) for q in (50, 90, 100)]}}
    for grid in args.grids.split(","):
        f, h = (int(v) for v in grid.split("x"))
        margin = margin_of(f)
        ex = BatchExpert(cfg, f, h, margin, s.slack_m, s.heavier, search="map")
        a, ok, secs = label(ex, x, t, target)
        ax, _ = ex.fire(x, t, target, a.astype(np.float64))
        err = np.abs(ax - target)
        both = ok & rok
        far = both & ~fin & (gone > 0)
        d = (err - rerr)[both] * 1e6
        rows[f"map {grid}"] = {
            "grid": grid, "margin": margin, "search": "map", "ms_per_state": secs / len(x) * 1e3,
            "full_firings_per_state": ex.full_firings / (len(x) + 2),
            "same_choice": float(np.mean(np.all(a == ra, axis=1))),
            "same_helps": float(np.mean(ok == rok)),
            "finishing_error_um": [float(np.percentile(err[fin], q) * 1e6)
                                   for q in (50, 90, 100)],
            "finishing_within_tolerance": float(np.mean(ok[fin] & (err[fin] <= cfg.tolerance))),
            "travel_over_reference": [float(np.percentile(
                (np.abs(x - target) - err)[far] / gone[far], q)) for q in (50, 10)],
            "landing_minus_reference_um": [float(v) for v in np.percentile(d, [1, 10, 50, 90,
                                                                                99])],
            "within_slack_of_reference": float(np.mean(d <= s.slack_m * 1e6 + 1e-9))}
    print(json.dumps({"states": len(x), "seed": args.seed, "experts": rows}, indent=1))


if __name__ == "__main__":
    main()
