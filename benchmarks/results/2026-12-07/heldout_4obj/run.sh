#!/bin/sh
# Issue 44, must hold 2: qLogNEHVI on the held-out four-objective problems, seeds 1.. (seed 0 and
# ours' seeds 0-4 with the reference given are in ../../2026-12-06/heldout_baseline/), one seed of
# each problem in turn, one core, one torch thread; each run appends its line to qlognehvi.jsonl.
#   sh benchmarks/results/2026-12-07/heldout_4obj/run.sh FIRST LAST
cd "$(dirname "$0")/../../../.." || exit 1
for seed in $(seq "${1:-1}" "${2:-4}"); do
  for problem in CarSideImpact "DTLZ2 (d=6, m=4)"; do
    OMP_NUM_THREADS=1 python benchmarks/mobo_quality.py --problems "$problem" --columns qLogNEHVI \
      --first-seed "$seed" --seeds 1 --botorch-seeds 1 --torch-threads 1 \
      --save benchmarks/results/2026-12-07/heldout_4obj/qlognehvi.jsonl
  done
done
