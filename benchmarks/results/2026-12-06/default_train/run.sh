#!/bin/bash
cd /tmp/mh4
for what in paper robust; do
  echo "== $what start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  if [ $what = paper ]; then args="--protocol paper"; else args=""; fi
  s=$(date +%s.%N)
  python -m mjxskill.train push $args --out /tmp/mh4/$what --quiet > /tmp/mh4/$what.log 2>&1
  e=$(date +%s.%N)
  echo "== $what wall $(echo "$e - $s" | bc) s, end load $(cut -d' ' -f1-3 /proc/loadavg)"
done
