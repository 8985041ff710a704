"""The agents' ``microconveyor`` commands, one module per family: ``reach``, ``optimize``,
``compare``, ``train``/``refine``/``convert-stats`` (:mod:`.rl`), ``evaluate``/``seeds``
(:mod:`.evaluate`), ``tune``/``train-seeds`` (:mod:`.tune`), ``place`` (one part to one
target), ``ship``/``record`` (the shipped policies), ``demo`` (the env package's physics
and env parts, :mod:`microconveyor_env.cli.demo`, and the env's default shipped policy) and
``video`` (a fixed schedule's episode, :mod:`microconveyor_env.cli.video`, or a policy's). Each
command name is defined in one module: registering one twice is an error.

Loaded through the ``microconveyor_env.commands`` entry point (pyproject.toml): importing this
package registers the commands with :func:`microconveyor_env.cli.base.command`.
"""
from . import compare, demo, evaluate, imitate, optimize, place, reach, rl, ship, tune, video  # noqa: F401 - importing registers the commands
