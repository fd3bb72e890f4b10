"""A local page to explore a run's Pareto front and pick a solution (``python -m mjxskill.explore``).

``data`` reads the runs of a directory into JSON documents, ``solutions`` computes a point's
per-world results and rendering on demand in a background thread, ``export`` writes what
``select --pick`` writes, ``server`` serves the page (``static/``: HTML, JavaScript, CSS and
the vendored D3 with its licence) and the API over them.
"""
