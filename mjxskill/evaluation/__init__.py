"""What follows training: the learned Pareto solutions against baselines (``baselines``), a
run's evaluation on disk (``evaluate_run``), the pick's validation in fresh worlds
(``validation``), repeated runs pooled (``pooled``), picking and exporting a solution
(``selection``) and rendering an episode (``render``)."""
