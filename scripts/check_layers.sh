#!/usr/bin/env bash
# The import-layer contract of pyproject.toml ([tool.importlinter]) checked on the package as
# users install it.  In an editable checkout import-linter reads the files under dss14_env/
# only and cannot see agents/, baselines/ and configs/, which the wheel installs as
# dss14_env.agents, dss14_env.baselines and dss14_env.configs; so the check installs the
# package (without its dependencies: import-linter reads source, it imports nothing) into a
# throw-away environment and runs there.  .ci/run does the same against the built wheel.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d /tmp/dss14-layers.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/src"  # the working tree's files, without an earlier build/ that setuptools would reuse
(cd "$repo" && git ls-files -z -co --exclude-standard | tar --null -T - -cf -) | tar -xf - -C "$tmp/src"
python3 -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q import-linter
"$tmp/venv/bin/python" -m pip install -q --no-deps "$tmp/src"
cd "$tmp"
"$tmp/venv/bin/lint-imports" --config "$repo/pyproject.toml"
