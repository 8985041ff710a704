#!/usr/bin/env bash
# Re-resolve requirements-lock.txt: every dependency of the package and of every extra, pinned.
# The lock is what the README's two commands and .ci/run install from (`pip install -c`); the
# package's own requirements (pyproject.toml) stay ranges. torch is held at the CPU build of the
# project's machines: any other release pulls several GB of CUDA packages.
#   bash scripts/refresh_lock.sh            # keep today's pins where they still fit
#   bash scripts/refresh_lock.sh --upgrade  # newest releases that fit the ranges
set -euo pipefail
cd "$(dirname "$0")/.."
tools="$(mktemp -d)"
trap 'rm -rf "$tools"' EXIT
python3 -m venv "$tools/venv"
"$tools/venv/bin/python" -m pip install -q 'pip-tools>=7.4,<8'
"$tools/venv/bin/pip-compile" --quiet --all-extras --strip-extras --allow-unsafe \
    --no-emit-index-url --no-emit-find-links --upgrade-package 'torch==2.13.0' \
    --output-file requirements-lock.txt "$@" pyproject.toml
# the pin names the release, not the build: `torch==2.13.0` takes the CPU wheel where one lies
# beside pip (the project's machines), PyPI's build elsewhere (a `+cpu` label is not on PyPI)
sed -i 's/^torch==\([^+]*\)+cpu$/torch==\1/' requirements-lock.txt
echo "wrote requirements-lock.txt: $(grep -c '==' requirements-lock.txt) pinned packages"
