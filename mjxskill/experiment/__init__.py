"""The paper's experiment, repeated and reported (``python -m mjxskill.experiment``).

R repetitions of the optimizer and R of uniform random search with the same budget, batches and
worlds; per repetition the paper's evaluation (the Pareto solutions, one picked solution,
planner-only, random sets, the operators' sets, on the known and unseen start configurations);
a report with figures side by side with the paper. ``directory``: the experiment on disk
(layout: ``mjxskill.runs.layout``); ``driver``: running it, resumably; ``stats``: the
numbers; ``figures`` and ``report``: report.json, report.md and the plots.
"""
