"""The repository's ``scripts/*.py`` as modules, for tests of the scripts that write docs and
figures (they are files, not an installed package)."""
import importlib.util
from pathlib import Path
from types import ModuleType

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def load_script(name: str) -> ModuleType:
    """``scripts/<name>.py`` executed as a fresh module named ``name``."""
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None, f"no script {name!r} in {SCRIPTS}"
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
