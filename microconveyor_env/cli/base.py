"""The ``microconveyor`` command line's machinery: the command registry, JSON output, argument
types and the error contract (see :mod:`microconveyor_env.cli`)."""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import sys
import threading
import traceback
from typing import Any, NamedTuple, NoReturn, TypeVar
from collections.abc import Callable, Mapping

from ..physics.materials import ParameterError

AddArgs = Callable[[argparse.ArgumentParser], None]


class Command(NamedTuple):
    """A registered command: ``run(args)``, its one-line help, ``add_args(parser)`` adding its
    options (None: none but ``--json``)."""

    run: Callable[[argparse.Namespace], Any]
    help: str
    add_args: AddArgs | None


# name -> the command; filled by :func:`command` only, one module per name
COMMANDS: dict[str, Command] = {}

Handler = TypeVar("Handler", bound=Callable[[argparse.Namespace], Any])


class DuplicateCommand(RuntimeError):
    """A command name registered by a second module (or twice by one): each name is defined
    once."""


def command(name: str, help_: str, add_args: AddArgs | None = None,
            ) -> Callable[[Handler], Handler]:
    """Register ``fn(args)`` as subcommand ``name`` (its options added by ``add_args``); a name
    registered before raises :class:`DuplicateCommand` naming both modules (a module imported
    again, as by ``importlib.reload``, replaces its own command)."""
    def deco(fn: Handler) -> Handler:
        old = COMMANDS.get(name)
        if old is not None and (_where(old.run) != _where(fn)):
            raise DuplicateCommand(f"command {name!r} is defined twice: in {old.run.__module__} "
                                   f"({old.run.__qualname__}) and in {fn.__module__} "
                                   f"({fn.__qualname__}); each command name is defined in one "
                                   "module")
        COMMANDS[name] = Command(fn, help_, add_args)
        return fn
    return deco


def _where(fn: Callable[..., Any]) -> tuple[str, str]:
    return fn.__module__, fn.__qualname__


def emit(args: argparse.Namespace, result: dict[str, Any], human: str = "") -> None:
    """Print ``result`` (SI values, unit-suffixed keys) as one JSON object with ``--json``, else
    ``human`` or one line per entry in the units people read (:mod:`.human`)."""
    if args.json:
        print(json.dumps(result, indent=None, default=json_default, allow_nan=False))
    else:
        from .human import format_result

        print(human or format_result(result))


def json_default(o: object) -> Any:
    """``json.dumps`` fallback: numpy scalars and arrays as Python numbers and lists."""
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


# ----------------------------------------------------------------------------- value parsing
def companion(plot: str, name: str) -> str:
    """The file beside ``--plot FILE`` for a command's further chart ``name``: ``DIR/STEM.png``
    -> ``DIR/STEM_name.png`` (every command takes a file; one with several charts writes the
    others beside it)."""
    from pathlib import Path

    path = Path(plot)
    return str(path.with_name(f"{path.stem}_{name}{path.suffix}"))


def plot_path(text: str) -> str:
    """``--plot`` value: a non-empty file name; without an extension ``.png`` is added (the
    reported path is the one written); the extension must be a format matplotlib writes."""
    from pathlib import Path

    if not text.strip():
        raise argparse.ArgumentTypeError("empty file name")
    path = Path(text)
    if text.endswith(("/", "\\")) or path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give a file name")
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    fmt = path.suffix[1:].lower()
    if fmt not in _plot_formats():
        raise argparse.ArgumentTypeError(f"unsupported chart format {fmt!r}; use one of "
                                         f"{', '.join(sorted(_plot_formats()))}")
    return str(path)


def _plot_formats() -> set[str]:
    from matplotlib.backend_bases import FigureCanvasBase

    return set(FigureCanvasBase.get_supported_filetypes())


def count(lo: int, hi: int | None = None) -> Callable[[str], int]:
    """An integer option in [lo, hi] (hi None: the library checks the upper bound)."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"must be an integer in [{lo}, "
                                             f"{'...' if hi is None else hi}], got {v}")
        return v
    return parse


# ----------------------------------------------------------------------------- settings as options
# A settings dataclass is a command's one source of options, defaults and help: a field whose
# ``metadata`` has "help" is an option. Its metadata (plain data, no import of this module):
#   "help"    the help text; "{default}" in it shows the field's default (read from the class:
#             a sequence joined by commas, pairs in it by colons, a float with :g; a format spec
#             applies to each number)
#   "flag"    the option string(s), a str or a tuple of aliases (default ``--name-with-dashes``)
#   "bounds"  (lo, hi) of an integer field, checked while parsing (hi None: no upper bound)
#   "parse"   the argparse type (default: from the field's type, int, float or str); a bool field
#             is a switch: default False, its flag sets True; default True, its flag (e.g.
#             ``--no-progress``) sets False
#   "choices", "metavar", "nargs"  as argparse's
# :func:`settings_options` adds the options (the command may give parsers and help of its own
# for some), :func:`settings_from` builds the dataclass from the parsed arguments.
OPTION = "help"


def _fields(cls: Any) -> tuple[Any, ...]:
    """The fields of a settings dataclass, or of the dataclass a ``functools.partial`` makes (a
    maker with some fields fixed)."""
    import dataclasses
    import functools

    made: Any = cls.func if isinstance(cls, functools.partial) else cls
    return dataclasses.fields(made)


def field_default(cls: type, name: str) -> Any:
    """The default of field ``name`` of the dataclass ``cls``, read from the class (no instance is
    built; a ``default_factory``'s value is made)."""
    import dataclasses

    f = next(f for f in _fields(cls) if f.name == name)
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise ValueError(f"{cls.__name__}.{name} has no default")


class _Shown:
    """A default as help shows it: sequences joined by commas (pairs in them by colons, as
    ``SIGMA:R,...``), floats with ``:g``."""

    def __init__(self, value: Any, sep: str = ",") -> None:
        self.value, self.sep = value, sep

    def __format__(self, spec: str) -> str:
        v = self.value
        if isinstance(v, (list, tuple)):
            return self.sep.join(format(_Shown(x, ":"), spec) for x in v)
        if isinstance(v, float) and not spec:
            return f"{v:g}"
        return format(v, spec)


def _kind(f: Any) -> str:
    """A field's type by name (its first alternative: ``int | None`` is ``int``)."""
    return f.type.__name__ if isinstance(f.type, type) else str(f.type).split("|")[0].strip()


def _field_parser(f: Any, meta: Any) -> Callable[[str], Any] | None:
    if "parse" in meta:
        return meta["parse"]
    kind = _kind(f)
    if kind == "int":
        lo, hi = meta.get("bounds", (None, None))
        return int if lo is None else count(lo, hi)
    return {"float": float, "str": None}.get(kind)


def settings_options(p: argparse.ArgumentParser, cls: type, names: list[str] | None = None, *,
                     parse: Mapping[str, Callable[[str], Any]] | None = None,
                     help_: Mapping[str, str] | None = None, unset: tuple[str, ...] = ()) -> None:
    """Add the options of the dataclass ``cls`` (its fields with a ``"help"`` in their metadata;
    ``names``: these fields, in this order): flag, parser, default and help from the field.
    ``parse`` and ``help_`` replace a field's parser or help text for this command; a field in
    ``unset`` defaults to None (the command fills it, e.g. from another option, before
    :func:`settings_from`; the help still shows the field's default)."""
    fields = {f.name: f for f in _fields(cls)}
    for name in names if names is not None else [n for n, f in fields.items()
                                                 if OPTION in f.metadata]:
        f = fields[name]
        meta = f.metadata
        if OPTION not in meta:
            raise ValueError(f"{cls.__name__}.{name} is not an option (no help in its metadata)")
        default = field_default(cls, name)
        flags = meta.get("flag", "--" + name.replace("_", "-"))
        flags = (flags,) if isinstance(flags, str) else tuple(flags)
        text = (help_ or {}).get(name, meta[OPTION])
        text = text.format(default=_Shown(default)) if "{" in text else text
        kw: dict[str, Any] = {"dest": name, "help": text.replace("%", "%%")}  # plain text
        if _kind(f) == "bool":
            kw.update(action="store_false" if default else "store_true", default=default)
        else:
            kw["default"] = None if name in unset else default
            parser = (parse or {}).get(name) or _field_parser(f, meta)
            if parser is not None:
                kw["type"] = parser
            for key in ("choices", "nargs", "metavar"):
                if key in meta:
                    kw[key] = meta[key]
            if "metavar" not in kw and "choices" not in kw:   # as argparse names it by the flag
                kw["metavar"] = flags[0].lstrip("-").replace("-", "_").upper()
        p.add_argument(*flags, **kw)


def settings_given(cls: type, args: argparse.Namespace) -> dict[str, Any]:
    """The parsed options of the fields of the dataclass ``cls`` that have a value (an option
    not given whose default is None, or unset, is left out: the field's default applies)."""
    return {f.name: getattr(args, f.name) for f in _fields(cls)
            if OPTION in f.metadata and getattr(args, f.name, None) is not None}


def settings_from(cls: type, args: argparse.Namespace, **fixed: Any) -> Any:
    """The dataclass ``cls`` from the parsed options of its fields (:func:`settings_given`),
    then ``fixed``."""
    return cls(**{**settings_given(cls, args), **fixed})


DEFAULT_PRESET = "feasibility"
PRESET_HELP = ("feasibility: chapter 3's surface; conveyor: chapter 4's; ke: uncalibrated; "
               "silicon, polysilicon, silicon_oxide, silicon_nitride, gold: MEMS pairs, pure KE; "
               "or a YAML path")


def shipped_presets() -> list[str]:
    """The names of the presets shipped with the package (``configs/*.yaml``), without loading
    any (argument parsing stays light)."""
    from importlib import resources

    files = resources.files("microconveyor_env.configs")
    return sorted(f.name[:-5] for f in files.iterdir() if f.name.endswith(".yaml"))


def preset_name(text: str) -> str:
    """``--preset`` value: a shipped preset's name (or a deprecated alias of one) or the path of
    an existing ``.yaml``/``.yml`` file; anything else is refused with the list of names."""
    from pathlib import Path

    names = shipped_presets()
    if text in names:
        return text
    path = Path(text)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return text
    from ..presets import RENAMED_PRESETS

    if text in RENAMED_PRESETS:
        return text
    raise argparse.ArgumentTypeError(f"unknown preset {text!r}; available: {', '.join(names)} "
                                     "(or a path to a .yaml file)")


def common_args(p: argparse.ArgumentParser) -> None:
    """The option of every command: ``--json``."""
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def preset_arg(p: argparse.ArgumentParser) -> None:
    """``--preset NAME`` of the physics and study commands: the surface they simulate."""
    p.add_argument("--preset", type=preset_name, default=DEFAULT_PRESET,
                   help=f"the surface simulated (default: {DEFAULT_PRESET}): {PRESET_HELP}")


DESCRIPTION = "microconveyor-env: micropart conveyor simulator, studies and agents"


class UsageError(ValueError):
    """A command line argparse refused (raised instead of printing usage and exiting)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message} (see --help)")


def build_parser() -> argparse.ArgumentParser:
    """The ``microconveyor`` parser with every registered command."""
    parser = _Parser(prog="microconveyor", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name, cmd in COMMANDS.items():
        p = sub.add_parser(name, help=cmd.help, description=cmd.help)
        common_args(p)
        if cmd.add_args is not None:
            cmd.add_args(p)
        p.set_defaults(func=cmd.run)
    return parser


# Errors that user input can cause: reported in one line, never with a traceback.
USER_ERRORS = (ParameterError, ValueError, RuntimeError, OSError, OverflowError, MemoryError,
               RecursionError)


# optional dependencies -> the extra that installs them (pyproject.toml)
EXTRAS = {"pandas": "studies", "pyarrow": "studies", "statsmodels": "studies", "SALib": "studies",
          "dask": "studies", "distributed": "studies", "stable_baselines3": "train",
          "torch": "train", "tensorboard": "train", "rich": "train", "cma": "agents",
          "rl_zoo3": "agents", "imageio": "render", "imageio_ffmpeg": "render",
          "pygame": "render"}


def missing_extra(exc: BaseException) -> str | None:
    """For an import of an optional dependency that is not installed: what to install."""
    if not isinstance(exc, ModuleNotFoundError) or not exc.name:
        return None
    extra = EXTRAS.get(exc.name.split(".")[0])
    if extra is None:
        return None
    return (f"this needs the optional package {exc.name.split('.')[0]!r}, which is not installed: "
            f"pip install 'microconveyor-env[{extra}]'")


def fail(argv: list[str], command: str, exc: BaseException) -> int:
    """The error contract: ``--json``: one ``{"error": ...}`` object on stdout; always one line on
    stderr; exit status 2."""
    extra = missing_extra(exc)
    expected = isinstance(exc, USER_ERRORS) or extra is not None
    text = extra or " ".join(str(exc).split()) or type(exc).__name__  # one line
    if not expected:
        text += " (internal error: please report it; MICROCONVEYOR_DEBUG=1 shows the traceback)"
    msg = f"{type(exc).__name__}: {text}"
    _report(argv, command, msg, type(exc).__name__)
    if not expected and os.environ.get("MICROCONVEYOR_DEBUG"):
        traceback.print_exception(exc)
    return 2


EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shells' convention for Ctrl-C


# A Ctrl-C whose KeyboardInterrupt is raised while Python runs a finalizer (``__del__``: numba's
# compiler objects free their LLVM handles there) is printed as "Exception ignored" and lost, and
# the command would run on and write its outputs (seen once in the Ctrl-C test, 2026-11-25).
# main() therefore latches every SIGINT; raise_if_interrupted() turns a lost one back into a
# KeyboardInterrupt where a command commits its outputs.
_sigint_seen = False


def _latch_sigint(signum: int, frame: Any) -> None:
    global _sigint_seen
    _sigint_seen = True
    raise KeyboardInterrupt


def raise_if_interrupted() -> None:
    """KeyboardInterrupt if a Ctrl-C reached this command (under :func:`main`), even one whose
    exception something swallowed."""
    if _sigint_seen:
        raise KeyboardInterrupt


def _install_sigint_latch() -> Callable[[], None]:
    """Latch SIGINT for this command (only over Python's own handler, in the main thread: an
    ignored SIGINT, as in a background job, stays ignored), and keep a latched interrupt that a
    finalizer dropped off stderr (the command reports it in its one line); returns the undo."""
    global _sigint_seen
    _sigint_seen = False
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        return lambda: None
    previous, previous_hook = signal.signal(signal.SIGINT, _latch_sigint), sys.unraisablehook

    def quiet_lost_interrupt(unraisable: Any) -> None:
        if not (_sigint_seen and unraisable.exc_type is KeyboardInterrupt):
            previous_hook(unraisable)

    sys.unraisablehook = quiet_lost_interrupt

    def undo() -> None:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook

    return undo


def interrupted(argv: list[str], command: str) -> int:
    """Ctrl-C (``KeyboardInterrupt``): ``--json``: one ``{"error": "interrupted", "error_type":
    "KeyboardInterrupt"}`` object on stdout; one line on stderr; exit status 130."""
    _report(argv, command, "interrupted", "KeyboardInterrupt")
    return EXIT_INTERRUPTED


def _report(argv: list[str], command: str, msg: str, error_type: str) -> None:
    """Under ``--json`` one ``{"error", "error_type"}`` object on stdout; one line on stderr."""
    if any(a.startswith("--j") and "--json".startswith(a) for a in argv):  # argparse abbrevs
        print(json.dumps({"error": msg, "error_type": error_type}), flush=True)
    print(f"microconveyor{' ' + command if command else ''}: {msg}", file=sys.stderr, flush=True)


_NEGATIVE = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def attach_negative_values(argv: list[str]) -> list[str]:
    """``--x0 -0.125e-3`` as ``--x0=-0.125e-3``: argparse takes a token that starts with ``-``
    and is not a plain negative number (``-1``, ``-0.5``; an exponent is enough to fail that
    test) for an option, and refuses the value. A negative number right after a ``--long``
    option without ``=`` is attached to it."""
    out: list[str] = []
    for tok in argv:
        if (_NEGATIVE.match(tok) and out and out[-1].startswith("--") and "=" not in out[-1]
                and out[-1] != "--"):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, the shells' status of a writer whose reader has gone


def main(argv: list[str] | None = None) -> int:
    """Run the command line (``argv``: the arguments, default ``sys.argv[1:]``); exit status.
    A reader of stdout that goes away (``microconveyor ... | head``) ends the command quietly
    (:func:`stdout_closed`)."""
    try:
        status = _run(argv)
        sys.stdout.flush()  # a reader gone shows here, not as a traceback at exit
        return status
    except BrokenPipeError:
        return stdout_closed()


def _run(argv: list[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = ""
    undo_latch = _install_sigint_latch()
    try:
        args = build_parser().parse_args(attach_negative_values(argv))
        command = args.command
        args.func(args)
    except KeyboardInterrupt:
        return interrupted(argv, command)
    except BrokenPipeError as exc:
        if reader_gone():
            raise  # stdout's: main ends quietly
        return fail(argv, command, exc)  # another pipe's
    except Exception as exc:  # noqa: BLE001 - the error contract covers every failure
        return fail(argv, command, exc)
    finally:
        undo_latch()
    return 0


def reader_gone() -> bool:
    """Whether stdout is a pipe whose reader has closed it (where ``poll`` can tell; elsewhere a
    broken pipe is taken to be stdout's)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # stdout replaced (captured): not a pipe
        return False
    import select

    if not hasattr(select, "poll"):
        return True
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(events & select.POLLERR for _, events in poller.poll(0))


def stdout_closed() -> int:
    """The end of a command whose stdout's reader has gone (the Python docs' "Note on
    SIGPIPE"): what is left of stdout goes to devnull, so the flush at exit fails no more, and
    nothing is printed; exit status :data:`EXIT_BROKEN_PIPE`."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (AttributeError, OSError, ValueError):  # stdout replaced: nothing left to flush
        pass
    return EXIT_BROKEN_PIPE
