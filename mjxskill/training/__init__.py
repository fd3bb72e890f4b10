"""Training and what follows it, as a library the commands drive: the run directory on disk
(``run_dir``), the optimizer loop (``loop``), the front and its hypervolume (``front``), the
scenario and plan of a run (``run_task``), figures and summaries (``report``), evaluation
against baselines (``evaluation``; a run's evaluation on disk: ``evaluate_run``; repeated runs
pooled: ``pooled``), picking and exporting a solution (``selection``), rendering an episode
(``render``), which runs a directory holds (``runs``) and the paper's experiment
(``experiment``). Nothing here parses arguments or exits: ``mjxskill.cli`` does.
"""
