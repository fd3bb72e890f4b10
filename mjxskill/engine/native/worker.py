"""A native engine worker process (started by ``mjxskill.engine.native.pool``; not a user command).

Reads a recipe frame (JSON) and a model frame (MJB bytes), builds the engine, answers ``K``;
then for every job frame (NPZ: params and world fields) runs the episodes on one single-threaded
MuJoCo batch (``NativeRollout.run_episodes``) and answers an ``O`` frame (NPZ: the
EpisodeResult fields). Any failure is answered with an ``E`` frame holding the traceback.
"""

from __future__ import annotations

import json
import signal
import sys
import traceback

import numpy as np

from mjxskill.engine.common.types import EpisodeResult
from mjxskill.engine.common.worlds import Worlds
from mjxskill.engine.native.pool import pack_arrays, read_frame, unpack_arrays, write_frame
from mjxskill.engine.native.rollout import engine_from_recipe


def main() -> int:
    # The parent handles Ctrl-C and stops us. Set aside only now, after the imports: ``python -m``
    # imports the package mjxskill.engine.native (NativeRollout, and with it every module above)
    # before this module, so importing them here first changes nothing.
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # anything printed by accident must not corrupt the frames
    try:
        kind, payload = read_frame(stdin)
        _, model = read_frame(stdin)
        engine = engine_from_recipe(json.loads(payload), model)
        write_frame(stdout, b"K", b"")
        while True:
            kind, payload = read_frame(stdin)
            arrays = unpack_arrays(payload)
            worlds = Worlds(*(arrays[f"world_{name}"] for name in Worlds._fields))
            results = engine.run_episodes(arrays["params"], worlds)
            fields = {f: np.array([getattr(r, f) for r in results]) for f in EpisodeResult._fields}
            write_frame(stdout, b"O", pack_arrays(**fields))
    except EOFError:  # the parent closed the pipe: done
        return 0
    except BaseException:  # noqa: BLE001  (reported to the parent, which raises it)
        try:
            write_frame(stdout, b"E", traceback.format_exc().encode())
        except OSError:
            pass
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
