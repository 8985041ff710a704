"""Chart where forked runs end against the per-seed bar of v1 (docs/agents.md, "What the last
third decides").

Each argument is ``LABEL=FOLDER[,FOLDER...]``: finished `microconveyor train` folders (their
``metadata.json``: the final evaluation on the monitored targets, and ``forks``, the state each
one was forked from). Writes ``OUT.json`` (per variant and run: the seed of the state it was forked
from, its forks (step, from seed, to seed), ±50 µm success [-] and median |error| [m]; per variant: how many runs meet the bar) and
``OUT.png`` (success against median, one panel per variant, the bar's corner shaded). Reads
metadata only: nothing is trained or evaluated here.

    python scripts/fork_outcomes.py --out docs/figures/ppo_v1_forks \
        "the recipe=runs/rec_s0_f21,runs/rec_s1_f21" "target KL 0.03=runs/kl_s0_f21"
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


from agents.plots.common import pyplot
from agents.rl.artefacts.checkpoint import read_meta

BAR_SUCCESS = 0.90       # - : >= 90 % within +-50 um
BAR_MEDIAN_M = 20e-6     # m : median |error| <= 20 um
X_MAX_UM, Y_MIN_PC = 50.0, 60.0  # the chart's window [um], [%]; runs outside sit on its edge


def run_row(folder: Path) -> dict:
    """The final figures of one finished run folder."""
    meta = read_meta(folder)
    ev = meta.get("evaluation") or {}
    if "success_rate_50um" not in ev:
        raise SystemExit(f"{folder}: no final evaluation in its metadata (not a finished run)")
    forks = meta.get("forks") or []
    first = forks[0] if forks else {}
    return {"folder": folder.name, "state_seed": first.get("from_seed", meta.get("seed")),
            "forks": forks, "seed": meta.get("seed"),
            "steps": meta.get("steps"), "success_rate_50um": ev["success_rate_50um"],
            "median_abs_error_m": ev["median_abs_error_m"],
            "at_bar": bool(ev["success_rate_50um"] >= BAR_SUCCESS
                           and ev["median_abs_error_m"] <= BAR_MEDIAN_M)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("variants", nargs="+", help="LABEL=FOLDER[,FOLDER...]")
    p.add_argument("--out", required=True, help="output stem: writes STEM.json and STEM.png")
    args = p.parse_args(argv)
    data = []
    for spec in args.variants:
        label, sep, folders = spec.partition("=")
        if not sep or not folders:
            raise SystemExit(f"expected LABEL=FOLDER[,FOLDER...], got {spec!r}")
        runs = [run_row(Path(f)) for f in folders.split(",")]
        data.append({"label": label, "runs": runs,
                     "at_bar": sum(r["at_bar"] for r in runs), "n": len(runs)})
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(
        {"bar": {"success_rate_50um": BAR_SUCCESS, "median_abs_error_m": BAR_MEDIAN_M},
         "variants": data}, indent=1) + "\n")
    plt = pyplot()
    fig, axes = plt.subplots(1, len(data), figsize=(3.2 * len(data), 3.4), sharex=True,
                             sharey=True, squeeze=False)
    seeds = sorted({r["state_seed"] for v in data for r in v["runs"]}, key=str)
    colours = {s: plt.get_cmap("tab10")(i % 10) for i, s in enumerate(seeds)}
    for ax, v in zip(axes[0], data, strict=True):
        ax.fill_between([0, BAR_MEDIAN_M * 1e6], BAR_SUCCESS * 100, 100, color="tab:green",
                        alpha=0.15, lw=0)
        for r in v["runs"]:
            x, y = r["median_abs_error_m"] * 1e6, r["success_rate_50um"] * 100
            # a run off the chart sits on its edge as an arrowhead pointing off it
            marker = ">" if x > X_MAX_UM else "v" if y < Y_MIN_PC else "o"
            ax.scatter(min(x, X_MAX_UM - 1), max(y, Y_MIN_PC + 1), s=22, marker=marker,
                       color=colours[r["state_seed"]], edgecolor="k", lw=0.4)
        ax.set_title(f"{v['label']}\n{v['at_bar']} of {v['n']} at the bar", fontsize=9)
        ax.set_xlabel("median |error| [µm]")
        ax.set_xlim(0, X_MAX_UM)
        ax.set_ylim(Y_MIN_PC, 100)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("within ±50 µm [%]")
    handles = [plt.Line2D([], [], ls="", marker="o", color=colours[s], label=f"state of seed {s}")
               for s in seeds]
    fig.legend(handles=handles, loc="lower center", ncol=len(seeds), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(out.with_suffix(".png"), dpi=110)
    for v in data:
        print(f"{v['label']}: {v['at_bar']} of {v['n']} runs at the bar")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
