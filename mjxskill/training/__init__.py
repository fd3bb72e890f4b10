"""Training and what follows it, as a library the commands drive: the run directory on disk
(``run_dir``), the optimizer loop (``loop``), the front and its hypervolume (``front``), the
scenario and plan of a run (``run_task``), figures and summaries (``report``), evaluation
against baselines (``evaluation``), picking and exporting a solution (``selection``) and
rendering an episode (``render``). Nothing here parses arguments or exits: ``mjxskill.cli`` does.
"""
