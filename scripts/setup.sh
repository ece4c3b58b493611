#!/bin/bash
# Idempotent set-up for a Debian 12 (bookworm) machine, run as root:
#   1. installs the Debian packages listed in scripts/packages.txt (only if some are missing),
#   2. builds the catkin workspace with Debian's /usr/bin/python3.
# A second run skips apt entirely and does an incremental catkin_make.
set -euo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

mapfile -t PKGS < <(sed -e 's/#.*//' -e '/^\s*$/d' scripts/packages.txt | tr -d ' ')
missing=()
for p in "${PKGS[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
if ((${#missing[@]})); then
  if [[ $(id -u) -ne 0 ]]; then
    echo "setup: missing Debian packages (${missing[*]}); run as root or install them" >&2
    exit 1
  fi
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${PKGS[@]}"
else
  echo "setup: all ${#PKGS[@]} Debian packages already installed"
fi

# PyPI-only tools (scripts/requirements-tools.txt) and the learning environment's libraries
# (scripts/requirements-learning.txt: gymnasium, pettingzoo) in a venv over Debian's python3,
# so that Debian's own python packages stay untouched; rebuilt when the requirements change
VENV="$ROOT/.venv"
REQS=(scripts/requirements-tools.txt scripts/requirements-learning.txt)
if [[ ! -x "$VENV/bin/python" ]] || ! cat "${REQS[@]}" | cmp -s - "$VENV/requirements.txt"; then
  echo "setup: installing the PyPI packages of ${REQS[*]} into .venv/"
  /usr/bin/python3 -m venv --system-site-packages "$VENV"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "${REQS[0]}" -r "${REQS[1]}"
  cat "${REQS[@]}" > "$VENV/requirements.txt"
fi

echo "setup: building the catkin workspace"
catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release > build.log 2>&1 || {
  tail -n 40 build.log >&2; echo "setup: catkin_make failed (full log: $ROOT/build.log)" >&2; exit 1; }
echo "setup: done (source devel/setup.bash to use the workspace)"
