#!/bin/bash
# Build the ORIGINAL patrolling_sim's eleven agent executables in a catkin workspace of their
# own, unmodified, for bench/original_agents.py and bench/original_matrix_queue.py
# (docs/fidelity.md, "The original's own agents in the abstract world").
#
# Usage: bench/build_original_agents.sh SRC WS [TARGET ...]
#   SRC     the original's source tree (a checkout of its public repository; package.xml
#           should say version 2.2.4, the version the fidelity matrix was measured with)
#   WS      the workspace to make (created if missing); SRC is copied to WS/src/patrolling_sim
#   TARGET  agent executables to build (default: all eleven)
#
# Debian 12 needs three things the original's build files do not say: the C++ headers of
# move_base_msgs, tf and roslib (installed here when missing), Boost's global bind
# placeholders on the compiler's command line (files use _1 without including
# boost/bind.hpp), and no optimisation: SSIPatrolAgent::compute_next_vertex() lacks its
# return statement, and only unoptimised does it return the value its last call computed.
# The targets are built one at a time (make -j1): the DTA agents need about 1 GB each.
# Exit status: 0 if every target built, 1 if one failed (the others are still built),
# 2 on bad arguments. Stops nothing it did not start.
set -uo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
ALL=(Random Conscientious_Reactive Heuristic_Conscientious_Reactive Conscientious_Cognitive
     Cyclic MSP GBS SEBS CBLS DTAGreedy DTASSIPart)

if [ $# -lt 2 ]; then
    echo "usage: $0 SRC WS [TARGET ...]" >&2
    exit 2
fi
src=$(realpath -m "$1"); ws=$(realpath -m "$2"); shift 2
targets=("$@"); [ ${#targets[@]} -eq 0 ] && targets=("${ALL[@]}")
if [ ! -f "$src/package.xml" ] || ! grep -q "<name>patrolling_sim</name>" "$src/package.xml"; then
    echo "build_original_agents.sh: SRC $src: no package.xml of patrolling_sim there" >&2
    exit 2
fi
for t in "${targets[@]}"; do
    if [[ ! " ${ALL[*]} " == *" $t "* ]]; then
        echo "build_original_agents.sh: TARGET $t: not one of ${ALL[*]}" >&2
        exit 2
    fi
done
version=$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$src/package.xml" | head -1)
[ "$version" = "2.2.4" ] || echo "note: the original's version is $version, the matrix used 2.2.4" >&2

missing=()
for p in libmove-base-msgs-dev libtf-dev libroslib-dev; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]}"
    (apt-get install -y -q "${missing[@]}" >/dev/null 2>&1 ||
        { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q "${missing[@]}" >/dev/null; }) ||
        { echo "build_original_agents.sh: could not install ${missing[*]}" >&2; exit 1; }
fi

mkdir -p "$ws/src" || exit 1
if [ "$src" != "$ws/src/patrolling_sim" ]; then
    rm -rf "$ws/src/patrolling_sim" && cp -a "$src" "$ws/src/patrolling_sim" || exit 1
fi
cd "$ws" || exit 1
log="$ws/build_original_agents.log"
echo "configuring $ws (log: $log)"
catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE= \
    "-DCMAKE_CXX_FLAGS=-DBOOST_BIND_GLOBAL_PLACEHOLDERS -include boost/bind.hpp -O0" \
    cmake_check_build_system > "$log" 2>&1 || { tail -20 "$log" >&2; exit 1; }
failed=()
for t in "${targets[@]}"; do
    if make -C "$ws/build" -j1 "$t" >> "$log" 2>&1; then
        echo "built $t"
    else
        echo "FAILED $t (see $log)" >&2
        failed+=("$t")
    fi
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "build_original_agents.sh: ${#failed[@]} of ${#targets[@]} failed: ${failed[*]}" >&2
    exit 1
fi
echo "all ${#targets[@]} built in $ws/devel/lib/patrolling_sim; use: --orig-ws $ws"
