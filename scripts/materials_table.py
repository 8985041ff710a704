"""The materials table of docs/physics.md §9: every shipped preset's inputs, contact figures and
feasible frequency window, computed by the package itself.

Run from the repository root::

    python3 scripts/materials_table.py            # print the table (Markdown)
    python3 scripts/materials_table.py --write    # replace it in docs/physics.md
    python3 scripts/materials_table.py --json     # the rows, SI units

For each preset (``microconveyor_env.presets.available_presets()``): roughness sigma, plasticity
index psi, work of adhesion dgamma and the asperity radius R they imply; ``Preset.forces()``
(pull-off force, friction Q at the part's weight, slip deceleration Q(m g0)/m); and the feasible
window of one firing, as ``microconveyor sweep`` finds it (``studies.sweep.sweep`` on its default
scene: one Gaussian actuator, wavelength 0.6 mm, stroke 200 um, start 0.125 mm beside it) over
``FREQS_HZ``, 100 Hz to 10 kHz (the upper end of the dissertation's optimisation range) in 25 Hz
steps: ``microconveyor sweep --preset NAME --freq 100:10000:25 --stroke 200e-6``. The window runs
from the lowest frequency that moves the part 10 um or more to the last one before the first
detachment; a sweep without one reports the reason ``studies.sweep.no_window_reason`` gives.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "physics.md"
START = "<!-- materials-table:start (scripts/materials_table.py --write) -->"
END = "<!-- materials-table:end -->"
FREQS_HZ = [100.0 + 25.0 * i for i in range(397)]  # 100:10000:25 [Hz]
STROKE_M = 200e-6                                   # the sweep's stroke [m] (Scene default)


def presets() -> list[str]:
    """Every shipped preset: the dissertation's (§8 order), then the others by name."""
    from microconveyor_env.presets import available_presets

    first = [n for n in ("feasibility", "conveyor", "ke") if n in available_presets()]
    return first + [n for n in available_presets() if n not in first]


def window(name: str, freqs: list[float] = FREQS_HZ) -> dict[str, Any]:
    """The feasible window [Hz] of preset ``name`` over ``freqs`` [Hz] (``window_hz`` [lo, hi] or
    None, then ``no_window_reason``), with the largest travel [m] and the number of detachments."""
    from microconveyor_env.studies.sweep import Scene, sweep

    res = sweep(Scene(preset=name, stroke=STROKE_M), "freq", freqs, progress=False)
    win = res["window_hz"]
    return {"freqs_hz": [freqs[0], freqs[-1], len(freqs)],
            "window_hz": None if win is None else [float(win[0]), float(win[1])],
            "no_window_reason": res.get("no_window_reason"),
            "max_travel_m": res.get("max_travel_m", 0.0),
            "detached": sum(o == "detached" for o in res["outcome"])}


def row(name: str, windows: bool = True) -> dict[str, Any]:
    """One preset's inputs and figures (SI units); ``windows``: run the two sweeps too."""
    from microconveyor_env.presets import load_preset

    p = load_preset(name)
    c = p.contact
    out: dict[str, Any] = {
        "preset": name, "description": p.description, "sigma_m": c.surface.sigma,
        "psi": c.surface.psi, "dgamma_J_m2": c.surface.dgamma,
        "asperity_radius_m": c.asperity_radius, "mass_kg": c.part.mass,
        "weight_N": c.part.weight, **p.forces()}
    if windows:
        out["sweep"] = window(name)
    return out


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def fmt(v: float) -> str:
    """Three significant digits, thousands separated; ``a.bc×10ⁿ`` from 10⁵ up."""
    if v == 0 or not math.isfinite(v):
        return f"{v:g}"
    mantissa, exponent = f"{v:.2e}".split("e")    # rounded to three significant digits once
    e = int(exponent)
    if e >= 5:
        return f"{mantissa}×10{str(e).translate(_SUPERSCRIPT)}"
    return f"{float(mantissa) * 10.0 ** e:,.{max(0, 2 - e)}f}"


def force_cells(r: dict[str, Any]) -> list[str]:
    """The table's force columns of row ``r``: pull-off [µN], Q at the weight [nN], slip
    deceleration [m/s²], then pull-off and Q in weights of the part [-]."""
    w = r["weight_N"]
    return [fmt(r["pull_off_force_N"] * 1e6), fmt(r["friction_at_weight_N"] * 1e9),
            fmt(r["slip_deceleration_m_s2"]), fmt(r["pull_off_force_N"] / w),
            fmt(r["friction_at_weight_N"] / w)]


def window_cell(w: dict[str, Any]) -> str:
    """``lo–hi Hz (up to N µm)``, or the reason there is none."""
    if w["window_hz"] is not None:
        lo, hi = w["window_hz"]
        return f"{lo:,.0f}–{hi:,.0f} Hz (up to {fmt(w['max_travel_m'] * 1e6)} µm)"
    return str(w["no_window_reason"] or "no window")


def markdown(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of ``rows``."""
    head = ("| preset | σ [nm] | ψ | Δγ [J/m²] | R [µm] | pull-off [µN] | Q at the weight [nN] "
            "| slip deceleration [m/s²] | pull-off ÷ weight | Q ÷ weight | feasible window "
            "(100 Hz–10 kHz) |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        cells = [f"`{r['preset']}`", f"{r['sigma_m'] * 1e9:g}", f"{r['psi']:g}",
                 f"{r['dgamma_J_m2']:g}", fmt(r["asperity_radius_m"] * 1e6), *force_cells(r),
                 window_cell(r["sweep"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write(text: str, doc: Path = DOC) -> None:
    """Replace what lies between the table's markers in ``doc`` with ``text``."""
    src = doc.read_text()
    if START not in src or END not in src:
        raise SystemExit(f"{doc}: the markers {START!r} and {END!r} are missing")
    head, rest = src.split(START, 1)
    _, tail = rest.split(END, 1)
    doc.write_text(f"{head}{START}\n{text}\n{END}{tail}")


def main(argv: list[str] | None = None) -> None:
    """The command line (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help=f"replace the table in {DOC.name}")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON (SI units)")
    ap.add_argument("--page", type=Path, default=DOC,
                    help=f"with --write: the page whose table is replaced (default {DOC.name})")
    args = ap.parse_args(argv)
    rows = []
    for name in presets():
        rows.append(row(name))
        print(f"{name}: done", file=sys.stderr)
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    text = markdown(rows)
    if args.write:
        write(text, args.page)
        print(f"wrote the table into {args.page}", file=sys.stderr)
    else:
        print(text)


if __name__ == "__main__":
    main()
