#!/bin/bash
# Batch template, like the original's run_exp.sh: edit the variables and the loop, then run
#   scripts/run_exp.sh
# Each experiment runs in sequence (start_experiments.py blocks until the run ends) with
# its own ROS master; results go to results/<MAP>_<NROBOTS>/<ALG>/<host>/.
# For parallel batches and value grids see: start_experiments.py --batch FILE --parallel J
set -u
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH

MAP=DIAG_labs          # grid example cumberland 1r5 broughton DIAG_labs DIAG_floor1 ctcv move_base_arena
NROBOTS=8
INITPOS=default        # default | a | b | c (variants of params/initial_poses.txt)
ALG=DTAP               # RAND CR HCR HPCC CGG MSP GBS SEBS CBLS DTAG DTAP
LOC=AMCL               # AMCL | fake_localization
NAV=spqrel_nav_lite    # spqrel_nav_lite | ros (real amcl/move_base where installed)
GWAIT=3                # goal_reached_wait (s)
COMMDELAY=0.2          # communication delay (s)
TERM=none              # accepted for compatibility; no terminal windows are opened
TIMEOUT=1800           # sim seconds after GO
CUSTOM_STAGE=false     # accepted for compatibility
SPEEDUP=1.0            # simulator pace (<= 0: as fast as possible)

failed=0
for run in 1 2 3; do
  echo "=== run $run: $MAP $NROBOTS $ALG"
  scripts/start_experiments.py $MAP $NROBOTS $INITPOS $ALG $LOC $NAV $GWAIT $COMMDELAY \
    $TERM $TIMEOUT $CUSTOM_STAGE $SPEEDUP --seed $run || failed=$((failed + 1))
done
echo "=== $failed failed run(s)"
exit $((failed > 0))
