"""An MJX call of a few hundred episodes finishes on the CPU with the settings a user gets.

With jax 0.10.2 a call of 6 sets x 60 worlds used to sit at 0 % CPU for ever, every XLA thread
parked (XLA:CPU's YNN fusion, jax issue 39257); importing mjxskill now switches that fusion
off (``mjxskill/_runtime.py``). The call runs in a fresh process, so that the process's
XLA_FLAGS are the ones ``import mjxskill`` sets, and under a timeout, so that a hang fails the
test instead of the suite."""

import json
import os
import subprocess
import sys

from cli_helpers import subprocess_env

CALL = """
import json, mjxskill, jax, numpy as np
from mjxskill import load_scenario, plan_task, compile_rollout
scn = load_scenario("push"); task = plan_task(scn)
rollout = compile_rollout(scn, task, worlds=60, episode_seconds=0.1)
out = rollout(np.tile(task.bounds.mean(axis=0), (6, 1)), jax.random.key(0))
print(json.dumps({"shape": list(np.shape(out.success)), "finite": bool(np.isfinite(np.asarray(out.objectives)).all())}))
"""


def test_a_call_of_360_episodes_finishes():
    env = {k: v for k, v in subprocess_env().items() if k != "XLA_FLAGS"}
    run = subprocess.run([sys.executable, "-c", CALL], env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout.strip().splitlines()[-1]) == {"shape": [6, 60], "finite": True}
