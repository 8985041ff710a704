"""The ``microconveyor`` command line.

Every subcommand accepts ``--json`` and then prints exactly one JSON object on stdout (SI units, keys
with unit suffixes); human-readable text and progress bars go to stderr. Errors exit with status 2
and, under ``--json``, print ``{"error": ...}``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

from .physics.materials import ParameterError

COMMANDS = {}


def command(name, help_):
    def deco(fn):
        COMMANDS[name] = (fn, help_)
        return fn
    return deco


def _emit(args, result: dict, human: str = "") -> None:
    if args.json:
        print(json.dumps(result, indent=None, default=_json_default))
    else:
        print(human or "\n".join(f"{k:32s} {v}" for k, v in result.items()))


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--preset", default="seed", help="preset name (seed, ke) or YAML path")


# ----------------------------------------------------------------------------- contact
def _contact_args(p):
    p.add_argument("--plot", metavar="FILE.png", help="draw P, F_s, N and Q versus separation")
    p.add_argument("--check-table", action="store_true",
                   help="also measure the table against direct quadrature")


@command("contact", "contact report of a preset (pull-off, friction at weight, separations)")
def cmd_contact(args):
    from .physics.contact_table import ContactTable, tabulation_error
    from .presets import load_preset

    preset = load_preset(args.preset)
    t0 = time.perf_counter()
    table = ContactTable(preset.contact)
    out = {"preset": preset.name, **table.report(),
           "table_build_s": table.base.build_seconds,
           "table_load_s": time.perf_counter() - t0,
           "calibration": preset.calibration}
    if args.check_table:
        out["table_error"] = tabulation_error(table)
    if args.plot:
        from .plots import plot_contact

        out["plot"] = str(plot_contact(table, args.plot, f"preset {preset.name}"))
    _emit(args, out)


# ----------------------------------------------------------------------------- demo
def _demo_args(p):
    p.add_argument("--out", default="out", help="output folder for charts and the summary JSON")


@command("demo", "the main job: contact report and charts of a preset, written to --out")
def cmd_demo(args):
    from pathlib import Path

    from .physics.contact_table import ContactTable
    from .plots import plot_contact
    from .presets import load_preset

    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    preset = load_preset(args.preset)
    table = ContactTable(preset.contact)
    summary = {"preset": preset.name, "contact": table.report(),
               "calibration": preset.calibration,
               "charts": [str(plot_contact(table, out_dir / "contact.png", f"preset {preset.name}"))]}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2, default=_json_default))
    summary["summary_json"] = str(out_dir / "summary.json")
    _emit(args, summary, f"wrote {', '.join(summary['charts'])} and {summary['summary_json']}")


_ARGS = {"contact": _contact_args, "demo": _demo_args}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="microconveyor", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (fn, help_) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        _common(p)
        _ARGS.get(name, lambda _p: None)(p)
        p.set_defaults(func=fn)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (ParameterError, ValueError, RuntimeError, OSError) as exc:
        msg = f"{type(exc).__name__}: {exc}"
        if getattr(args, "json", False):
            print(json.dumps({"error": msg, "error_type": type(exc).__name__}))
        print(f"microconveyor {args.command}: {msg}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
