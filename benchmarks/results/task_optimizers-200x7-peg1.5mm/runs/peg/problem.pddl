(define (problem peg-task)
  (:domain peg)
  (:objects peg-1 - item boxwithhole-1 - item home-1 - pose table-1 - item iiwa-1 - robot)
  (:init
    (ee-at iiwa-1 home-1)
    (holding iiwa-1 peg-1)
    (has-hole boxwithhole-1))
  (:goal (and (at peg-1 boxwithhole-1))))
