"""The ``microconveyor`` command line.

Every subcommand accepts ``--json`` and then prints exactly one JSON object on stdout (SI units, keys
with unit suffixes); human-readable text and progress bars go to stderr. Every error (a bad
argument included) exits with status 2 and one line on stderr and, under ``--json``, prints one
``{"error": ..., "error_type": ...}`` object on stdout; never a traceback.

Commands live in one module per group (``contact``, ``simulation``, ``studies``) and register
themselves with :func:`.base.command`; each command name is defined in one module (a second
registration of a name is an error). Packages built on this one (the agents) add their commands
through the ``microconveyor_env.commands`` entry-point group: each entry point names a module that
registers its commands when imported. ``demo`` and ``video`` are the agents' (they run a policy
too); their physics and env parts are :mod:`.demo` and :mod:`.video` here.
"""
from __future__ import annotations

from importlib.metadata import entry_points

from . import contact, simulation, studies  # noqa: F401  (register their commands)
from .base import (COMMANDS, DuplicateCommand, UsageError, build_parser, command, emit,
                   main)

ENTRY_POINT_GROUP = "microconveyor_env.commands"


def _load_plugins() -> None:
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        ep.load()


_load_plugins()

__all__ = ["COMMANDS", "DuplicateCommand", "UsageError", "build_parser", "command", "emit", "main"]
