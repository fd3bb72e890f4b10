#!/bin/bash
# Issue 45 must hold 1: the same evaluations.csv before (1f6288f, before the redesign) and after
# (HEAD) on both engines, with workers and on a local Ray cluster.
set -u
OUT=/work/mh1/out; mkdir -p $OUT
FLAGS="--budget 12 --batch-size 6 --init 6 --worlds 2 --episode-seconds 3 --seed 0"
for REV in 1f6288f HEAD; do  # HEAD was fac1067 when this ran
  WT=/work/mh1/wt-$REV
  [ -d $WT ] || git -C /work/main worktree add --detach $WT $REV >/dev/null 2>&1
  SCN=$WT/assets/scenarios/push.yaml
  for V in "native:--engine native --workers 1" "workers2:--engine native --workers 2" "mjx:--engine mjx" "ray:--engine native --ray-address auto"; do
    NAME=${V%%:*}; ARGS=${V#*:}
    D=$OUT/$REV-$NAME; rm -rf $D
    if [ $NAME = ray ]; then ray start --head --num-cpus 2 --disable-usage-stats >/dev/null 2>&1; fi
    ( cd $WT && PYTHONPATH=$WT timeout 1200 python -m mjxskill.train $SCN $FLAGS $ARGS --out $D > $OUT/$REV-$NAME.log 2>&1 ); echo "$REV $NAME rc=$? $(date +%T)"
    if [ $NAME = ray ]; then ray stop --force >/dev/null 2>&1; fi
  done
done
for NAME in native workers2 mjx ray; do
  cmp -s $OUT/1f6288f-$NAME/evaluations.csv $OUT/HEAD-$NAME/evaluations.csv && echo "$NAME same" || echo "$NAME DIFFERENT"
done
