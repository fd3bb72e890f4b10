"""The twin calibrated from a robot's recordings (``python -m mjxskill.calibrate``, issue 49).

``recording`` (the format of one executed episode and its checked reader), ``record`` (recordings
made in a twin: the loop without a robot), ``twin`` (the scenario's declared physical values as
``mujoco.sysid`` parameters with their ``MjSpec`` modifiers, and twins with other values),
``replay`` (the closed-loop replay of a recorded episode and the residual over its window),
``fit`` (``mujoco.sysid``'s optimizer and intervals over them), ``report`` and ``scenario_yaml``
(what a fit writes). ``mujoco.sysid`` needs the optional extra ``mjxskill[calibrate]``
(``missing_extra`` says what is absent); every module imports without it.
"""

from __future__ import annotations

import importlib.util

# what mujoco.sysid imports beyond mjxskill's own dependencies (mujoco[sysid]'s extra)
SYSID_MODULES = ("absl", "colorama", "imageio", "jinja2", "plotly", "tabulate")


def missing_extra() -> str | None:
    """Why ``mujoco.sysid`` cannot run here (what is absent, and what to install), or None."""
    absent = [m for m in SYSID_MODULES if importlib.util.find_spec(m) is None]
    if not absent:
        return None
    return (f"calibrate fits with mujoco's system identification toolbox, mujoco.sysid, whose "
            f"{', '.join(absent)} {'is' if len(absent) == 1 else 'are'} not installed: pip install 'mjxskill[calibrate]'")


__all__ = ["SYSID_MODULES", "missing_extra"]
