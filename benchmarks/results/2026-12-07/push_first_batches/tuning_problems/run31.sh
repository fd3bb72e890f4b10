#!/bin/bash
cd /work/main
D=benchmarks/results/2026-12-07/push_first_batches/tuning_problems
NOISY=("BraninCurrin, noisy" "ZDT1 (d=6), noisy" "DTLZ2 (d=6, m=3), noisy")
echo "start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $D/fit_tol1e-6.jsonl --option fit_gradient_tolerance=1e-6
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/noisy_fit_tol1e-6.jsonl --option fit_gradient_tolerance=1e-6
echo "end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
