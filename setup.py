"""Which packages the distribution holds, found rather than listed (metadata: pyproject.toml).

Every package under ``microconveyor_env/`` and ``agents/`` is found by setuptools; the repository's
top-level ``configs/`` folder (presets, env defaults, hyperparameter files) installs as the
``microconveyor_env.configs`` package, with its sub-folders. ``tests/test_packaging.py`` builds
the wheel and checks that every module and config file is in it.
"""
from setuptools import find_namespace_packages, find_packages, setup

CONFIGS = "microconveyor_env.configs"
config_packages = [CONFIGS + name[len("configs"):]
                   for name in find_namespace_packages(include=["configs", "configs.*"])]
setup(packages=find_packages(include=["microconveyor_env", "microconveyor_env.*", "agents",
                                      "agents.*"]) + config_packages,
      package_dir={name: name.replace(CONFIGS, "configs", 1).replace(".", "/")
                   for name in config_packages})
