#!/bin/sh
# NOTES 45: the per-step loop (OLD: a worktree at the commit before) against the control callback
# (NEW: this tree), one slice of the training batch, alternately, one core, nothing else running.
#   OLD=/work/wt-old NEW=/work/main sh benchmarks/results/2026-12-07/batch_step/ab_callback.sh > FILE
for task in ${TASKS:-push peg}; do
  for round in $(seq 1 ${ROUNDS:-3}); do
    for wt in "$OLD" "$NEW"; do
      echo "== $wt round $round"
      (cd "$wt" && PYTHONPATH="$wt" OMP_NUM_THREADS=1 taskset -c 0 python "$NEW/benchmarks/results/2026-12-07/batch_step/slices.py" $task 0 2 2>&1 | grep -v Warn)
    done
  done
done
