"""The native engine's worker pool leaves nothing on disk: the workers
get the MuJoCo model as bytes through their pipe, so a parent killed with SIGKILL mid-call
leaves no model file in the temporary folder, and the workers' results still equal one
process's."""

import os
import signal
import subprocess
import sys
import time

from cli_helpers import subprocess_env

SCRIPT = """
import sys
import jax, numpy as np
import mjxskill
from mjxskill.engine.native import NativeRollout, ProcessPoolRollout
from mjxskill.runs.run_task import scenario_and_task

scn, task = scenario_and_task("push")
params = np.asarray(task.bounds).mean(axis=0)[None].repeat(2, axis=0)
pooled = ProcessPoolRollout(NativeRollout(scn, task, worlds=2, episode_seconds=0.3), workers=2)
alone = NativeRollout(scn, task, worlds=2, episode_seconds=0.3)
key = jax.random.key(0)
a, b = pooled(params, key), alone(params, key)
assert np.array_equal(np.asarray(a.objectives), np.asarray(b.objectives)), (a.objectives, b.objectives)
print("equal", " ".join(str(p.pid) for p in pooled.start().procs), flush=True)
long = ProcessPoolRollout(NativeRollout(scn, task, worlds=8, episode_seconds=30.0), workers=2)
long(params, key)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_a_killed_pool_leaves_no_model_file(tmp_path):
    temp = tmp_path / "tmp"
    temp.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=subprocess_env(TMPDIR=str(temp)))
    with proc:
        try:
            line = proc.stdout.readline()
            assert line.startswith("equal "), (line, proc.stderr.read() if proc.poll() is not None else "")
            workers = [int(pid) for pid in line.split()[1:]]
            time.sleep(3)  # the long call's workers are running episodes
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
    for _ in range(300):  # the first pool's workers see their pipes close and exit
        if not any(_alive(pid) for pid in workers):
            break
        time.sleep(0.1)
    assert sorted(str(p.relative_to(temp)) for p in temp.rglob("*")) == []
