#!/bin/bash
cd /work/main
D=benchmarks/results/2026-12-07/push_first_batches/tuning_problems
NOISY=("BraninCurrin, noisy" "ZDT1 (d=6), noisy" "DTLZ2 (d=6, m=3), noisy")
echo "start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $D/draws.jsonl --option pending=draws
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $D/dim_scaled.jsonl --option prior=dim_scaled
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/noisy_defaults.jsonl
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/noisy_dim_scaled_draws.jsonl --option prior=dim_scaled --option pending=draws
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/noisy_draws.jsonl --option pending=draws
python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $D/noisy_dim_scaled.jsonl --option prior=dim_scaled
echo "end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
