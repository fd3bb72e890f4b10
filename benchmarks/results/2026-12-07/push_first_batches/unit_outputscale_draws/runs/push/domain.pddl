(define (domain push)
  (:requirements :strips :typing)
  (:types location robot - object pose item - location)
  (:predicates
    (at ?a0 - item ?a1 - location)
    (ee-at ?a0 - robot ?a1 - location)
    (holding ?a0 - robot ?a1 - item)
    (pushable ?a0 - item)
    (has-hole ?a0 - item)
    (can-push ?a0 - robot))
  (:action gotolinear
    :parameters (?robot - robot ?from - location ?target - location)
    :precondition (and (ee-at ?robot ?from))
    :effect (and (ee-at ?robot ?target) (not (ee-at ?robot ?from))))
  (:action push
    :parameters (?robot - robot ?workpiece - item ?goal - pose)
    :precondition (and (ee-at ?robot ?workpiece) (pushable ?workpiece) (can-push ?robot))
    :effect (and (at ?workpiece ?goal)))
  (:action peginsertion
    :parameters (?robot - robot ?peg - item ?box - item)
    :precondition (and (ee-at ?robot ?box) (has-hole ?box) (holding ?robot ?peg))
    :effect (and (at ?peg ?box))))
