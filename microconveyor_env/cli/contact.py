"""``microconveyor contact``: the contact law of a preset."""
from __future__ import annotations

import argparse
import time
from typing import Any

from .base import command, emit, plot_path, preset_arg


def _contact_args(p: argparse.ArgumentParser) -> None:
    preset_arg(p)
    p.add_argument("--plot", metavar="FILE.png", type=plot_path,
                   help="draw P, F_s, N and Q versus separation")
    p.add_argument("--check-table", action="store_true",
                   help="also measure the table against direct quadrature")


@command("contact", "contact report of a preset (pull-off, friction at weight, separations)",
         _contact_args)
def cmd_contact(args: argparse.Namespace) -> None:
    """Report the preset's contact characteristics (SI, unit-suffixed keys)."""
    from ..physics.contact_table import ContactTable, tabulation_error
    from ..presets import load_preset

    preset = load_preset(args.preset)
    t0 = time.perf_counter()
    table = ContactTable(preset.contact)
    out: dict[str, Any] = {"preset": preset.name, **table.report(),
           "table_build_s": table.base.build_seconds,
           "table_load_s": time.perf_counter() - t0,
           "calibration": preset.calibration}
    if args.check_table:
        out["table_error"] = tabulation_error(table)
    if args.plot:
        from ..plots import plot_contact

        out["plot"] = str(plot_contact(table, args.plot, f"preset {preset.name}"))
    emit(args, out)

