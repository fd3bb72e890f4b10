(define (problem slide-task)
  (:domain slide)
  (:objects block-1 - item slot-1 - pose home-1 - pose table-1 - item pusher-1 - item iiwa-1 - robot)
  (:init
    (ee-at iiwa-1 home-1)
    (can-push iiwa-1)
    (slidable block-1)
    (holding iiwa-1 pusher-1))
  (:goal (and (at block-1 slot-1))))
