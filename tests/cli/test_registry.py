"""The command registry: each command name is defined in one module, and a second registration
of a name is an error naming both modules, never a silent replacement."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def registry(monkeypatch):
    """The live registry, copied: a test's registrations leave the real one as it was."""
    from microconveyor_env.cli import base

    monkeypatch.setattr(base, "COMMANDS", dict(base.COMMANDS))
    return base


def _handler(module, name="cmd"):
    def fn(args):
        return None

    fn.__module__, fn.__qualname__ = module, name
    return fn


def test_a_name_registered_twice_raises_naming_both_modules(registry):
    first = _handler("pkg.one")
    registry.command("twice", "the first")(first)
    with pytest.raises(registry.DuplicateCommand,
                       match=r"'twice' is defined twice: in pkg\.one .* and in pkg\.two"):
        registry.command("twice", "the second")(_handler("pkg.two"))
    assert registry.COMMANDS["twice"].run is first   # the first stays


def test_the_env_package_cannot_replace_an_agents_command(registry):
    """``demo`` is the agents' command; a second ``demo`` (as the env package once defined)
    fails when it registers."""
    with pytest.raises(registry.DuplicateCommand,
                       match=r"in agents\.cli\.demo .* and in microconveyor_env\.cli\.demo"):
        registry.command("demo", "the env's demo")(_handler("microconveyor_env.cli.demo"))


def test_the_same_module_imported_again_replaces_its_own_command(registry):
    """``importlib.reload`` re-runs a module's registrations: the same function of the same
    module is no second definition."""
    registry.command("again", "help")(_handler("pkg.one"))
    again = _handler("pkg.one")
    registry.command("again", "help")(again)
    assert registry.COMMANDS["again"].run is again


def _definitions() -> dict[str, list[str]]:
    """Command name -> the source modules that register it (``@command("name", ...)`` or
    ``command("name", ...)`` with a literal name)."""
    out: dict[str, list[str]] = {}
    for path in sorted([*ROOT.glob("microconveyor_env/**/*.py"), *ROOT.glob("agents/**/*.py")]):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "command"
                    and node.args and isinstance(node.args[0], ast.Constant)):
                out.setdefault(node.args[0].value, []).append(str(path.relative_to(ROOT)))
    return out


def test_every_command_name_is_defined_in_one_module():
    from microconveyor_env.cli import COMMANDS

    defs = _definitions()
    twice = {name: mods for name, mods in defs.items() if len(mods) > 1}
    assert not twice, twice
    # every registered command is found (the studies' loop registers names from a table)
    literal = set(defs) | {"sensitivity", "engage", "fidelity", "firing-map", "stretch"}
    assert set(COMMANDS) <= literal, set(COMMANDS) - literal
