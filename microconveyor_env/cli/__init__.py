"""The ``microconveyor`` command line.

Every subcommand accepts ``--json`` and then prints exactly one JSON object on stdout (SI units, keys
with unit suffixes); human-readable text and progress bars go to stderr. Every error (a bad
argument included) exits with status 2 and one line on stderr and, under ``--json``, prints one
``{"error": ..., "error_type": ...}`` object on stdout; never a traceback.

Commands live in one module per group (``contact``, ``simulation``, ``demo``, ``studies``,
``video``) and register themselves with :func:`.base.command`. Packages built on this one (the
agents) add their commands through the ``microconveyor_env.commands`` entry-point group: each
entry point names a module that registers its commands when imported.
"""
from __future__ import annotations

from importlib.metadata import entry_points

from . import contact, demo, simulation, studies, video  # noqa: F401  (register their commands)
from .base import COMMANDS, UsageError, build_parser, command, emit, main

ENTRY_POINT_GROUP = "microconveyor_env.commands"


def _load_plugins() -> None:
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        ep.load()


_load_plugins()

__all__ = ["COMMANDS", "UsageError", "build_parser", "command", "emit", "main"]
