"""mjxskill's shipped data, no code: the scenarios (``scenarios/``), the skill library
(``skills/``) and the MJCF scenes (``*.xml``, ``tools/``). Installed as the package
``mjxskill.assets`` (pyproject.toml maps it onto this folder) and found through
``importlib.resources`` by ``mjxskill.sim.scene.asset_path``."""
