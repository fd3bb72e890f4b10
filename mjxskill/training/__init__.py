"""Training as a library the commands drive: the optimizer loop (``loop``) and the optimizers it
takes (``optimizers``: ``make_optimizer``, one ``init``/``ask``/``tell`` interface), the run's parameter
prior (``priors``), the front and its hypervolume (``front``), a run's figures and summaries
(``report``). Nothing here parses arguments or exits: ``mjxskill.cli`` does."""
