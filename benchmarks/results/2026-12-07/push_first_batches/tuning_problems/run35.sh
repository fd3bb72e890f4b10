#!/bin/bash
cd /work/main
D=benchmarks/results/2026-12-07/push_first_batches
T=$D/tuning_problems
NOISY=("BraninCurrin, noisy" "ZDT1 (d=6), noisy" "DTLZ2 (d=6, m=3), noisy")
run() { OMP_NUM_THREADS=1 taskset -c 0 "$@"; }
echo "start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
run python benchmarks/task_optimizers.py --tasks push --methods mjxskill.gp --seeds 10 --budget 102 --optimizer-option prior=unit_outputscale --optimizer-option pending=draws --out $D/unit_outputscale_draws
echo "push done $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
run python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $T/unit_outputscale_draws.jsonl --option prior=unit_outputscale --option pending=draws
run python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $T/noisy_unit_outputscale_draws.jsonl --option prior=unit_outputscale --option pending=draws
echo "tuning 1 done $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
run python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --save $T/small_noise_draws.jsonl --option prior=small_noise --option pending=draws
run python benchmarks/mobo_quality.py --columns mjxskill.gp --seeds 10 --problems "${NOISY[@]}" --save $T/noisy_small_noise_draws.jsonl --option prior=small_noise --option pending=draws
echo "end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
