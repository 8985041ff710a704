"""The agents' ``microconveyor`` commands, one module per family: ``reach``, ``optimize``,
``compare``, ``train``/``refine``/``convert-stats`` (:mod:`.rl`), ``evaluate``/``seeds``
(:mod:`.evaluate`), ``tune``/``train-seeds`` (:mod:`.tune`), ``place`` (one part to one
target), ``demo`` (which replaces the env package's demo with one that also runs the
shipped policy) and ``video`` (which replaces the env package's with one that also films a
policy).

Loaded through the ``microconveyor_env.commands`` entry point (pyproject.toml): importing this
package registers the commands with :func:`microconveyor_env.cli.base.command`.
"""
from . import compare, demo, evaluate, imitate, optimize, place, reach, rl, tune, video  # noqa: F401 - importing registers the commands
