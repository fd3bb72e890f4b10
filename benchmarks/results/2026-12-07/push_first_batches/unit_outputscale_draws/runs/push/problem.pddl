(define (problem push-task)
  (:domain push)
  (:objects objecttobepushed-1 - item objectgoalpose-1 - pose home-1 - pose table-1 - item pusher-1 - item iiwa-1 - robot)
  (:init
    (ee-at iiwa-1 home-1)
    (can-push iiwa-1)
    (pushable objecttobepushed-1)
    (holding iiwa-1 pusher-1))
  (:goal (and (at objecttobepushed-1 objectgoalpose-1))))
