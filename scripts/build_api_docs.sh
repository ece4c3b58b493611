#!/bin/bash
# Build the API reference from the docstrings: `make docs` -> build/docs/index.html.
# Any Sphinx warning is an error (exit non-zero). Sources are generated into build/api-src.
set -euo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/build/docs}"
SRC="$(mktemp -d)"
trap 'rm -rf "$SRC"' EXIT
cp "$ROOT/docs/api/conf.py" "$ROOT/docs/api/index.rst" "$SRC/"
for pkg in patrolling_sim/src/patrolling_sim spqrel_nav_lite/src/spqrel_nav_lite; do
  sphinx-apidoc -q -e -M -o "$SRC/modules" "$ROOT/src/$pkg"
done
rm -f "$SRC/modules/modules.rst"
export PYTHONPATH="$ROOT/src/patrolling_sim/src:$ROOT/src/spqrel_nav_lite/src${PYTHONPATH:+:$PYTHONPATH}"
sphinx-build -q -W --keep-going -b html "$SRC" "$OUT"
echo "docs: $OUT/index.html"
