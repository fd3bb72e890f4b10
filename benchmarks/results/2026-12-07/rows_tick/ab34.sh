#!/bin/bash
# NOTES 33 and 34 outcomes: the other jobs stopped (SIGSTOP), one run after the other
out=/work/main/benchmarks/results/2026-12-07/rows_tick
mkdir -p $out
for task in push peg; do
  for w in wt-old main; do
    tag=$([ $w = main ] && echo after || echo before)
    echo "$task $tag $(date +%T) $(uptime)"
    (cd /work/$w && PYTHONPATH=/work/$w python benchmarks/throughput.py --task $task --devices 0 --workers 1,2 --threads 1 --json $out/throughput-$task-$tag.json 2>&1 | grep -E "^native|^loop|best engine|own physics \(" )
  done
done
echo "end $(date +%T) $(uptime)"
