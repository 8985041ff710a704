"""``microconveyor sensitivity | engage | fidelity | firing-map | stretch``: the studies (``..studies``).

Each takes ``--json`` (one JSON object on stdout), ``--plot FILE.png``, ``--out FILE.csv`` or
``.parquet`` (the tidy table, one row per simulation), ``--workers N`` (local Dask cluster) or
``--scheduler ADDRESS`` (an existing one, reached within ``--scheduler-timeout`` seconds), and
shows a progress bar on stderr.

``--out`` and ``--plot`` are checked before any work (a supported suffix, an existing writable
folder). The files are written only once everything is computed, each to a temporary file beside
it, renamed into place together at the end: an error or Ctrl-C leaves no partial output.
"""
from __future__ import annotations

import argparse
import os
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from collections.abc import Callable

from .base import command, count, emit, plot_path, preset_arg, raise_if_interrupted
from .human import format_result


def table_path(text: str) -> str:
    """``--out`` value: a ``.csv`` or ``.parquet`` file name in an existing writable folder (the
    ``.parquet`` format needs pyarrow)."""
    from importlib.util import find_spec

    from ..studies.engine import TABLE_SUFFIXES

    path = _file_in_writable_folder(text)
    if path.suffix not in TABLE_SUFFIXES:
        raise argparse.ArgumentTypeError(f"{text!r}: use a .csv or .parquet file name")
    if path.suffix == ".parquet" and find_spec("pyarrow") is None:
        raise argparse.ArgumentTypeError(f"{text!r}: .parquet needs pyarrow (pip install pyarrow); "
                                         "or use .csv")
    return text


def chart_path(text: str) -> str:
    """``--plot`` value: :func:`.base.plot_path` (a format matplotlib writes, ``.png`` added to a
    name without one) in an existing writable folder."""
    path = plot_path(text)
    _file_in_writable_folder(path)
    return path


def _file_in_writable_folder(text: str) -> Path:
    """``text`` as a path: not a folder, and its folder exists and is writable."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty file name")
    path = Path(text)
    if text.endswith(("/", "\\")) or path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give a file name")
    folder = path.parent
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text!r}: folder {str(folder)!r} is not writable")
    return path


def positive_seconds(text: str) -> float:
    """A duration option [s]: a positive finite number."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return v


def _engine_args(p: argparse.ArgumentParser, out_default: str) -> None:
    from ..studies.engine import SCHEDULER_TIMEOUT_S

    preset_arg(p)
    p.add_argument("--out", default=out_default, type=table_path,
                   help="result table, .csv or .parquet (one row per simulation)")
    p.add_argument("--plot", metavar="FILE.png", type=chart_path, help="write the chart")
    p.add_argument("--workers", type=count(0), default=0,
                   help="run on a local Dask cluster of N worker processes (0: serial)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--scheduler-timeout", type=positive_seconds, default=SCHEDULER_TIMEOUT_S,
                   metavar="SECONDS", help="give up connecting to --scheduler after this long "
                                           f"(default {SCHEDULER_TIMEOUT_S:g})")
    p.add_argument("--chunk-size", type=count(1), default=None,
                   help="tasks per Dask task (default: about four per worker)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def _engine_kw(args: argparse.Namespace) -> dict[str, Any]:
    return {"workers": args.workers or None, "scheduler": args.scheduler,
            "scheduler_timeout": args.scheduler_timeout, "chunk_size": args.chunk_size,
            "progress": not args.no_progress}


def _with_engine(args: argparse.Namespace, body: Callable[[dict[str, Any], float], None]) -> None:
    """``body(engine keywords, cluster start-up time [s])`` with one Dask client for all of a
    command's runs when ``--workers``/``--scheduler`` is given."""
    kw = _engine_kw(args)
    workers, scheduler = kw.pop("workers"), kw.pop("scheduler")
    timeout = kw.pop("scheduler_timeout")
    if not (workers or scheduler):
        return body(kw, 0.0)
    from ..studies.engine import dask_client

    t0 = time.perf_counter()
    with dask_client(workers, scheduler, timeout) as client:
        return body({**kw, "client": client}, time.perf_counter() - t0)


class Outputs:
    """A command's output files, staged: :meth:`stage` names a temporary file beside the final
    one (same suffix, so writers pick the same format); :func:`outputs` renames them all into
    place at the end, or removes them on an error or Ctrl-C."""

    def __init__(self) -> None:
        self.staged: list[tuple[Path, Path]] = []  # (temporary, final)

    def stage(self, final: str | Path) -> str:
        """A temporary path to write ``final``'s content to."""
        from ..studies.engine import partial_path

        tmp = partial_path(final)
        self.staged.append((tmp, Path(final)))
        return str(tmp)

    def table(self, rows: list[dict[str, Any]], final: str) -> str:
        """Stage the table of ``rows`` for ``final`` (``.csv``/``.parquet``); returns ``final``."""
        from ..studies.engine import write_table

        write_table(rows, self.stage(final))
        return str(Path(final))

    def commit(self) -> None:
        """Rename every staged file onto its final path."""
        for tmp, final in self.staged:
            os.replace(tmp, final)
        self.staged.clear()

    def discard(self) -> None:
        """Remove the staged files written so far."""
        for tmp, _ in self.staged:
            tmp.unlink(missing_ok=True)
        self.staged.clear()


@contextmanager
def outputs() -> Iterator[Outputs]:
    """Staged output files (:class:`Outputs`): committed on a clean exit, discarded otherwise
    (also after a Ctrl-C whose exception was swallowed: :func:`.base.raise_if_interrupted`)."""
    files = Outputs()
    try:
        yield files
        raise_if_interrupted()
        files.commit()
    except BaseException:
        files.discard()
        raise


def _values(spec: str, name: str) -> tuple[Any, ...]:
    from ..studies.sweep import parse_values

    return tuple(parse_values(spec, name))


# ----------------------------------------------------------------------------- sensitivity
QUICK_LEVELS = {"dgamma_J_m2": (1.0,), "sigma_m": (20e-9, 30e-9), "stroke_m": (150e-6, 200e-6),
                "mass_kg": (2e-9,), "wavelength_m": (0.6e-3,), "x0_wl": (0.2, 0.25)}


def _sensitivity_args(p: argparse.ArgumentParser) -> None:
    _engine_args(p, "sensitivity.csv")
    p.add_argument("--n-freq", type=count(1, 10_000), default=None,
                   help="design frequencies per combination (default 8, --quick 4)")
    p.add_argument("--sobol-n", type=count(0), default=None,
                   help="Sobol' base sample size N (power of 2; N (2D+2) runs); 0: skip "
                        "(default 128, --quick 4)")
    p.add_argument("--quick", action="store_true",
                   help="a 8-combination design, 4 design frequencies and N = 4 Sobol' sample "
                        "(smoke test; an explicit --n-freq or --sobol-n wins)")


def cmd_sensitivity(args: argparse.Namespace) -> None:
    """The sensitivity design (Box-Cox + OLS) and Sobol' indices of the travel [m]."""
    from ..studies.sensitivity import LEVELS

    levels = QUICK_LEVELS if args.quick else LEVELS
    n_freq = args.n_freq if args.n_freq is not None else 4 if args.quick else 8
    sobol_n = args.sobol_n if args.sobol_n is not None else 4 if args.quick else 128
    _with_engine(args, lambda kw, startup: _sensitivity(args, levels, n_freq, sobol_n, kw,
                                                         startup))


def _sensitivity(args: argparse.Namespace, levels: Mapping[str, Sequence[float]], n_freq: int,
                 sobol_n: int, kw: dict[str, Any], startup: float) -> None:
    from ..studies import regression, sobol
    from ..studies.sensitivity import sensitivity_rows, windows

    t0 = time.perf_counter()
    rows = sensitivity_rows(levels, n_freq=n_freq, preset=args.preset, **kw)
    design_wall = time.perf_counter() - t0
    table = regression.table34(rows)
    out: dict[str, Any] = {"preset": args.preset, "levels": levels, "combinations": len(windows(rows)),
           "runs": len(rows), "design_runs": sum(r["phase"] == "design" for r in rows),
           "empty_windows": sum(w["window_hz"] is None for w in windows(rows)),
           "wall_time_s": design_wall, "workers": args.workers, "scheduler": args.scheduler,
           "cluster_startup_s": startup, "table34": table}
    sob = srows = None
    if sobol_n:
        t0 = time.perf_counter()
        srows = sobol.sobol_rows(sobol_n, preset=args.preset, **kw)
        sob = sobol.indices(srows)
        sob["wall_time_s"] = time.perf_counter() - t0
        out["sobol"] = sob
    with outputs() as files:
        out["table"] = files.table(rows, args.out)
        if srows is not None:
            stem = args.out.rsplit(".", 1)
            out["sobol_table"] = files.table(srows, f"{stem[0]}_sobol.{stem[1]}")
        if args.plot:
            from ..studies.plots_studies import plot_sensitivity

            plot_sensitivity(table, sob, files.stage(args.plot))
            out["plot"] = str(Path(args.plot))
    text = regression.table34_text(table)
    if sob:
        text += "\nSobol' indices (S1 +- CI, ST +- CI):\n" + "\n".join(
            f"  {i['name']:16s} S1 {i['S1']:6.3f} +- {i['S1_conf']:.3f}   ST {i['ST']:6.3f} +- "
            f"{i['ST_conf']:.3f}" for i in sob["indices"])
        text += f"\ninteracting: {', '.join(sob['interacting']) or 'none'}"
    emit(args, out, text)


# ----------------------------------------------------------------------------- engage
def _engage_args(p: argparse.ArgumentParser) -> None:
    _engine_args(p, "engage.csv")
    p.add_argument("--freqs", default="300,500,700", help="map frequencies [Hz], list or a:b:c")
    p.add_argument("--stroke", type=float, default=150e-6, help="map stroke h [m]")
    p.add_argument("--x0", default="-0.6e-3:0.6e-3:0.025e-3",
                   help="map start positions [m] relative to the actuator (use --x0=-...)")
    p.add_argument("--v0", default="-0.5:0.5:0.01", help="map initial velocities [m/s]")
    p.add_argument("--two-freq", type=float, default=950.0, help="two-actuator frequency [Hz]")
    p.add_argument("--two-stroke", type=float, default=200e-6, help="two-actuator stroke [m]")
    p.add_argument("--start-offset", type=float, default=0.125e-3,
                   help="two actuators: start this far upstream of the first [m]")
    p.add_argument("--spacing", default="0.2e-3:1.5e-3:0.05e-3", help="spacings [m]")
    p.add_argument("--delay", default="0:8e-3:0.2e-3", help="delays of the second firing [s]")


def cmd_engage(args: argparse.Namespace) -> None:
    """The engaging map (travel [m] over v0 [m/s] and x0 [m]) and the two-actuator map."""
    _with_engine(args, lambda kw, startup: _engage(args, kw))


def _engage(args: argparse.Namespace, kw: dict[str, Any]) -> None:
    from ..studies.engage import (check_speed_statement, engage_map_rows, summarise_two,
                         two_actuator_rows)

    t0 = time.perf_counter()
    mrows = engage_map_rows(_values(args.freqs, "freq"), args.stroke, _values(args.x0, "x0"),
                            _values(args.v0, "v0"), preset=args.preset, **kw)
    trows = two_actuator_rows(args.two_freq, args.two_stroke, args.start_offset,
                              spacings=_values(args.spacing, "spacing"),
                              delays=_values(args.delay, "delay"), preset=args.preset, **kw)
    wall = time.perf_counter() - t0
    stem = args.out.rsplit(".", 1)
    check = check_speed_statement(mrows)
    for m in ("travel_along_m", "gain_along_m"):
        if m in check:
            check[m].pop("per_start", None)
    out: dict[str, Any] = {"preset": args.preset, "map_runs": len(mrows),
           "map_detached": sum(r["detached"] for r in mrows), "speed_statement": check,
           "two_actuators": summarise_two(trows), "wall_time_s": wall}
    with outputs() as files:
        out["table"] = files.table(mrows, args.out)
        out["two_table"] = files.table(trows, f"{stem[0]}_two.{stem[1]}")
        if args.plot:
            from ..studies.plots_studies import plot_engage

            plot_engage(mrows, trows, files.stage(args.plot))
            out["plot"] = str(Path(args.plot))
    emit(args, out)


# ----------------------------------------------------------------------------- fidelity
def _fidelity_args(p: argparse.ArgumentParser) -> None:
    _engine_args(p, "fidelity.csv")
    p.add_argument("--repeats", type=count(1, 10_000), default=3,
                   help="timed repeats per level")
    p.add_argument("--scenes", default="single,episode_near,episode_far",
                   help="comma-separated scenes: single (the reference firing), episode_near and "
                        "episode_far (5 firings ending near the start and ~2 mm downstream)")


def cmd_fidelity(args: argparse.Namespace) -> None:
    """Each model level's error [m] against the most faithful one, and its wall time [s]."""
    from ..studies.fidelity import SCENES, assess, fidelity_rows

    scenes = tuple(s.strip() for s in args.scenes.split(",") if s.strip())
    bad = [s for s in scenes if s not in SCENES]
    if bad:
        raise ValueError(f"unknown scenes {bad}; available: {sorted(SCENES)}")
    t0 = time.perf_counter()
    rows = fidelity_rows(scenes, repeats=args.repeats, preset=args.preset, **_engine_kw(args))
    res = assess(rows)
    res["wall_time_s"] = time.perf_counter() - t0
    with outputs() as files:
        res["table"] = files.table(res["rows"], args.out)
        if args.plot:
            from ..studies.plots_studies import plot_fidelity

            plot_fidelity(res, files.stage(args.plot))
            res["plot"] = str(Path(args.plot))
    res.pop("rows")
    shown = {k: v for k, v in res.items() if k != "scenes"}   # described in --json and --help
    emit(args, res, format_result({**shown, "scenes_run": list(scenes)}))


# ----------------------------------------------------------------------------- firing maps
def _map_args(p: argparse.ArgumentParser) -> None:
    from ..studies.fidelity import MAP_ENV_IDS

    p.add_argument("--env", action="append", default=None, choices=MAP_ENV_IDS,
                   help="an env id whose firing map to check; repeat for more (default: every "
                        f"scene with one: {', '.join(MAP_ENV_IDS)})")
    p.add_argument("--samples", type=count(10, 10_000_000), default=5000,
                   help="held-out strokes per map, drawn over its grid's box")
    p.add_argument("--seed", type=count(0, 2**31 - 1), default=12345,
                   help="seed of the held-out strokes")


def cmd_firing_map(args: argparse.Namespace) -> None:
    """Each scene's firing map against the full model: error [m] and wall time [s]."""
    from ..studies.fidelity import MAP_ENV_IDS, map_rows

    ids = list(dict.fromkeys(args.env or MAP_ENV_IDS))
    t0 = time.perf_counter()
    rows = map_rows(ids, args.samples, args.seed)
    import datetime
    import sys

    out = {"maps": rows, "samples": args.samples, "seed": args.seed,
           "wall_time_s": time.perf_counter() - t0,
           "command": " ".join(["microconveyor", *sys.argv[1:]]),
           "recorded_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}
    lines = []
    for r in rows:
        lines.append(
            f"{r['env_id']} ({'firings from rest' if r['from_rest'] else 'moving parts'}): "
            f"{r['nodes']:,} strokes tabulated in {r['build_s']:.1f} s; "
            f"{'at rest' if r['from_rest'] else 'at the end of the stroke'}: trusted "
            f"{r['trusted_share']:.0%} of {r['samples']:,} held-out strokes, error median "
            f"{r['error_median_m'] * 1e6:.2f} µm, 99th percentile {r['error_p99_m'] * 1e6:.1f} "
            f"µm, max {r['error_max_m'] * 1e6:.1f} µm ({r['relative_error_max']:.2%} of the "
            f"displacement at most), {r['misclassified_detachments']} trusted strokes detach on "
            f"the full model, {r['untrusted_on_surface_share']:.1%} untrusted that stay on; "
            f"{r['map_query_s'] * 1e6:.2f} µs per query against "
            f"{r['full_stroke_s'] * 1e6:.1f} µs per full-model stroke ({r['speedup']:.0f}x)")
        if r["at_rest"]:
            a = r["at_rest"]
            lines.append(f"  where the part then comes to rest: error median "
                         f"{a['error_median_m'] * 1e6:.2f} µm, 99th percentile "
                         f"{a['error_p99_m'] * 1e6:.1f} µm, max {a['error_max_m'] * 1e6:.1f} µm")
    emit(args, out, "\n".join(lines))


# ----------------------------------------------------------------------------- stretch
def _stretch_args(p: argparse.ArgumentParser) -> None:
    _engine_args(p, "stretch.csv")
    p.add_argument("--freq", default="200:1500:25", help="frequencies [Hz], list or a:b:c")
    p.add_argument("--stroke", type=float, default=200e-6, help="stroke h [m]")
    p.add_argument("--x0", type=float, default=0.125e-3, help="start position [m]")
    p.add_argument("--profile", default="gaussian", help="gaussian, sinusoidal, clamped_beam")
    p.add_argument("--wavelength", type=float, default=0.6e-3, help="wavelength WL [m]")
    p.add_argument("--kinematics", default="reduced", choices=("reduced", "exact", "seed"),
                   help="reduced (the dissertation's model) or exact; 'seed' is the former name")
    p.add_argument("--repeats", type=count(1, 10_000), default=3, help="timed repeats per run")
    p.add_argument("--n-sigma", type=count(2, 1000), default=21,
                   help="sigma nodes of the stretch tables")


def cmd_stretch(args: argparse.Namespace) -> None:
    """Travel [m] versus frequency [Hz] with constant and stretch-dependent roughness."""
    from ..presets import simulator
    from ..studies.stretch_study import compare, stretch_rows

    t0 = time.perf_counter()
    sim = simulator(args.preset, shape=args.profile, wavelength=args.wavelength,
                    roughness="stretch", n_sigma=args.n_sigma)  # build/load the tables once
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    rows = stretch_rows(_values(args.freq, "freq"), args.stroke, args.x0, args.profile,
                        args.wavelength, args.repeats, args.preset,
                        {"kinematics": args.kinematics, "n_sigma": args.n_sigma},
                        **_engine_kw(args))
    out: dict[str, Any] = {"preset": args.preset, "stroke_m": args.stroke, "x0_m": args.x0,
           "profile": args.profile, "kinematics": args.kinematics,
           "peak_strain": sim.peak_strain(args.stroke), "stretch_setup_s": setup,
           "sigma_nodes": len(sim.stretch.tables), "max_strain": sim.stretch.max_strain,
           **compare(rows), "wall_time_s": time.perf_counter() - t0}
    with outputs() as files:
        out["table"] = files.table(rows, args.out)
        if args.plot:
            from ..studies.plots_studies import plot_stretch

            plot_stretch({"rows": rows}, files.stage(args.plot))
            out["plot"] = str(Path(args.plot))
    emit(args, out)


for _name, _help, _fn, _add in (
        ("sensitivity", "the dissertation's sensitivity design: Box-Cox + OLS and Sobol' indices",
         cmd_sensitivity, _sensitivity_args),
        ("engage", "engaging velocity/position maps and the two-actuator map",
         cmd_engage, _engage_args),
        ("fidelity", "which model level a scene needs: error against the most faithful level "
                     "and cost", cmd_fidelity, _fidelity_args),
        ("firing-map", "each scene's firing map (one stroke tabulated on the full model): its "
                       "error against the full model on held-out strokes, and its speed",
         cmd_firing_map, _map_args),
        ("stretch", "travel versus frequency with constant and stretch-dependent roughness, and "
                    "its cost", cmd_stretch, _stretch_args)):
    command(_name, _help, _add)(_fn)
