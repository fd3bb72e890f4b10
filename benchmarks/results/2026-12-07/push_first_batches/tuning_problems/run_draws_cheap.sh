#!/bin/bash
cd /work/main
D=benchmarks/results/2026-12-07/push_first_batches
echo "start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
python benchmarks/task_optimizers.py --tasks push --methods mjxskill.gp --seeds 10 --budget 102 --optimizer-option pending=draws --optimizer-option n_restarts=5 --out $D/draws_restarts5
python benchmarks/task_optimizers.py --tasks push --methods mjxskill.gp --seeds 10 --budget 102 --optimizer-option pending=draws --optimizer-option n_draws=8 --out $D/draws_ndraws8
echo "end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
