#!/bin/bash
# NOTES 27: pending=draws with n_opt_steps=60 on the tuning set (smooth and noisy) and the push at budget 102.
cd /work/main
D=benchmarks/results/2026-12-07/push_first_batches
NOISY=("BraninCurrin, noisy" "ZDT1 (d=6), noisy" "DTLZ2 (d=6, m=3), noisy")
echo "start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $D/tuning_problems/draws_steps60.jsonl --option pending=draws --option n_opt_steps=60
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/tuning_problems/noisy_draws_steps60.jsonl --option pending=draws --option n_opt_steps=60
python benchmarks/task_optimizers.py --tasks push --methods mjxskill.gp --seeds 10 --budget 102 --optimizer-option pending=draws --optimizer-option n_opt_steps=60 --out $D/draws_steps60
echo "end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
