"""The impedance law as MuJoCo's control callback (``mjcb_control``), so that one
``Batch.step(rows, nstep=steps)`` runs a tick's control steps of every row in C: MuJoCo steps a
row's whole tick before the next row's (its data stays in the cache), and no Python runs between
two steps (benchmarks/NOTES.md sections 44 and 45).

The callback is a numba ``cfunc``. A row's ``userdata`` (the model's last ``CONTROL_USERDATA``
numbers, ``mjxskill.sim.model``) holds the address of the batch's ``ControlContext`` and the row's
index; the context holds, per row, the tick's references and command, the law's rate-limited
state, what the law reads of the step before, and the tick's touch force sums. The ``mjData``
being stepped is read through its pointer members, whose places in the struct come from
mjData's declaration order (``mujoco.introspect``), checked once per engine against the arrays'
addresses in two ``mjData`` (``data_offsets``). The compiled law (``kernels.control_step``) sits
in ``kernels`` beside the law it calls, so that numba's cache of it goes stale with that file.

What the law reads is what it reads between two ``mj_step`` calls: the state (``qpos``, ``qvel``)
now, and the site pose, ``cdof``, ``subtree_com`` and ``qfrc_bias`` of the forward pass before
(what ``mj_step`` leaves in the data, one step behind the state). Inside ``mj_step`` the data
holds the current forward pass's, so the callback keeps the previous step's in the context (its
``stash``) and uses those: whole episodes equal the per-step loop's and the numpy lockstep's bit
for bit. A step's touch force (an acceleration-stage sensor, computed after the callback) is
read by the next step's callback, the tick's last one from the bound ``sensordata`` after the
call (``ControlContext.end_tick``): the same values summed in the same order.

The callback is installed only while a batch steps (``installed``: one batch of a process at a
time) and acts only for data whose ``userdata`` names a context of a batch stepping now (the
process's table of live contexts, ``ControlContext.bind`` and ``release``): a row MuJoCo reset
(its ``userdata`` zero again), or data of another model stepped meanwhile, is left alone. A
model integrated with RK4 (four forward passes a step) is refused by the engine.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import threading

import mujoco
import numba
import numpy as np
from mujoco.introspect import ast_nodes, structs
from numba import types

from mjxskill.engine.native.kernels import (ARRAYS, FIELDS, HEADER, MAGIC, SCRATCH, STASH, _ARRAYS, _CHAIN, _MAGIC, _NSENSOR,
                                            _OFFSETS, _ROOT, _ROWS, _SITE, _STEPS, _f64, _i64, add_forces, control_step,
                                            keep_kinematics)
from mjxskill.sim.controller_config import N_ARM
from mjxskill.sim.model import CONTROL_USERDATA

_SCAN_WORDS = 1 << 20  # a bound on the search for the anchor field, which sits in the struct (~160 kB in MuJoCo 4)


def _pointer_run() -> list[str]:
    """mjData's pointer members from ``buffer`` on, in declaration order (``mujoco.introspect``):
    consecutive 8-byte words of the struct, so a member's word is the run's first plus its index."""
    fields = structs.STRUCTS["mjData"].fields
    start = [f.name for f in fields].index("buffer")
    run = []
    for f in fields[start:]:
        if not isinstance(f.type, ast_nodes.PointerType):
            break
        run.append(f.name)
    return run


def data_offsets(model: mujoco.MjModel) -> tuple[int, ...]:
    """The words (8 bytes each, from the struct's start) of the ``FIELDS`` pointers in an ``mjData``
    of ``model``: each member's own word, from mjData's declaration order (an empty array shares
    its address with the next one, so a value alone cannot tell them apart), the run's place found
    from one array's address and checked against every other non-empty array's of the data's
    buffer, in two mjData. RuntimeError if they disagree (a MuJoCo whose mjData differs from its
    ``introspect``)."""
    run = _pointer_run()
    datas = mujoco.MjData(model), mujoco.MjData(model)
    exposed = [(j, name, getattr(datas[0], name)) for j, name in enumerate(run)
               if isinstance(getattr(datas[0], name, None), np.ndarray)]
    addresses = [a.ctypes.data for _, _, a in exposed]
    start = datas[0].qpos.ctypes.data  # the buffer's first array; arrays in the arena move from step to step
    unique = [(j, name) for (j, name, a), address in zip(exposed, addresses)
              if a.size and addresses.count(address) == 1 and start <= address < start + datas[0].nbuffer]
    anchor_index, anchor = unique[0]

    def misplaced(first: int) -> list[str]:
        return [name for data in datas for j, name in unique
                if ctypes.c_int64.from_address(data._address + 8 * (first + j)).value != getattr(data, name).ctypes.data]

    # the anchor's value may sit in an earlier member too (``buffer`` starts where ``qpos`` does):
    # the first word with it where every array is then in its place; the anchor's own word, in
    # the struct, ends the search at the latest
    word, base, address, wrong = 0, datas[0]._address, getattr(datas[0], anchor).ctypes.data, list(FIELDS)
    while wrong and word < _SCAN_WORDS:
        if ctypes.c_int64.from_address(base + 8 * word).value == address:
            wrong = misplaced(word - anchor_index)
        word += 1
    if wrong or any(name not in run for name in FIELDS):
        raise RuntimeError(f"the native engine cannot read MuJoCo {mujoco.__version__}'s mjData: "
                           f"{', '.join(sorted(set(wrong)) or [n for n in FIELDS if n not in run])} not where expected")
    first = word - 1 - anchor_index
    return tuple(first + run.index(name) for name in FIELDS)


# the contexts of the batches stepping in this process: the callback acts only for data whose
# userdata names one of them (another model stepped meanwhile is left alone)
_LIVE = np.zeros(64, np.int64)
_INSTALL = threading.Lock()


@functools.lru_cache(maxsize=None)
def callback(userdata_word: int, slot: int):
    """The ``cfunc`` (m, d) for data whose ``userdata`` pointer is at ``userdata_word`` of the
    struct and whose context sits at ``userdata[slot]`` (its row at ``slot + 1``). Compiled once
    per process and layout (~0.03 s: ``kernels.control_step`` comes from numba's cache); the two
    numbers and the live contexts' table are constants of it, so no machine code outlives them."""
    live, n_live = _LIVE.ctypes.data, len(_LIVE)

    @numba.cfunc(types.void(types.int64, types.int64))
    def control(m, d):
        userdata = _f64(_i64(d)[userdata_word])
        header = np.int64(userdata[slot])
        if header == 0:  # a row MuJoCo reset, or data of another model
            return
        table = numba.carray(_i64(live), n_live)
        for k in range(n_live):
            if table[k] == header:
                control_step(d, header, np.int64(userdata[slot + 1]))
                return
    return control


class ControlContext:
    """What the callback reads and writes for the n rows of a batch stepping ``steps`` control
    steps a call: per row the tick's references, command and touch force sums (filled by
    ``begin_tick``, read by ``end_tick``), the law's rate-limited state ``torque``, ``stiffness``
    and ``wrench`` (the caller's (n, 7), (n, 6), (n, 6) float64 arrays, updated in place) and
    ``nullspace_target`` (n, 7), and the stash of what the law reads of the step before. ``bind``
    writes the context into the rows' ``userdata``."""

    def __init__(self, offsets: tuple[int, ...], steps: int, cfg, chain: np.ndarray, root: int, sensors: np.ndarray,
                 torque: np.ndarray, stiffness: np.ndarray, wrench: np.ndarray, nullspace_target: np.ndarray):
        n = len(torque)
        for name, array, width in (("torque", torque, N_ARM), ("stiffness", stiffness, 6), ("wrench", wrench, 6),
                                   ("nullspace_target", nullspace_target, N_ARM)):
            if array.shape != (n, width) or array.dtype != np.float64 or not array.flags.c_contiguous:
                raise ValueError(f"{name} must be a C-contiguous float64 ({n}, {width}) array, got {array.dtype} {array.shape}")
        self.refs, self.stash, self.scratch = np.zeros((n, steps, 7)), np.zeros((n, STASH)), np.zeros((n, SCRATCH))
        self.cmd_wrench, self.cmd_stiffness = np.zeros((n, 6)), np.zeros((n, 6))
        self.nullspace_target, self.torque, self.stiffness, self.wrench = nullspace_target, torque, stiffness, wrench
        self.counter, self.force_sum, self.force_peak = np.zeros(n), np.zeros(n), np.zeros(n)
        self.limits = np.concatenate([np.asarray(cfg.torque_limit, float),
                                      [cfg.stiffness_rate * cfg.dt, cfg.wrench_rate * cfg.dt, cfg.torque_step,
                                       cfg.pinv_damping, cfg.nullspace_stiffness]])
        self.sensors = np.ascontiguousarray(sensors, dtype=np.int64)
        self.header = np.zeros(HEADER, np.int64)
        self.header[[_MAGIC, _ROWS, _STEPS, _SITE, _ROOT, _NSENSOR]] = MAGIC, n, steps, cfg.site_id, root, len(self.sensors)
        self.header[_OFFSETS:_CHAIN], self.header[_CHAIN:_ARRAYS] = offsets, np.asarray(chain, np.int64)
        self.header[_ARRAYS:] = [getattr(self, name).ctypes.data for name in ARRAYS]

    def bind(self, userdata: np.ndarray, fields: dict) -> None:
        """Points every row's ``userdata`` (the batch's bound (n, nuserdata) field) at this context,
        makes it one the callback acts for (until ``release``), and fills the stash from the bound
        fields after the batch's first forward pass."""
        if len(userdata) != int(self.header[_ROWS]):
            raise ValueError(f"{len(userdata)} rows of userdata for a context of {int(self.header[_ROWS])}")
        with _INSTALL:
            free = np.flatnonzero(_LIVE == 0)
            if not len(free):
                raise RuntimeError(f"more than {len(_LIVE)} native batches stepping in one process")
            _LIVE[free[0]] = self.header.ctypes.data
        site, root = int(self.header[_SITE]), int(self.header[_ROOT])
        userdata[:, -CONTROL_USERDATA] = float(self.header.ctypes.data)  # below 2**53: exact in a double
        userdata[:, 1 - CONTROL_USERDATA] = np.arange(len(userdata))
        for i in range(len(userdata)):
            keep_kinematics(self.stash[i], fields["site_xpos"][i, site], fields["site_xmat"][i, site],
                            fields["subtree_com"][i, root], fields["cdof"][i].reshape(-1), fields["qfrc_bias"][i])

    def release(self) -> None:
        """The callback no longer acts for this context (its arrays may go)."""
        with _INSTALL:
            _LIVE[_LIVE == self.header.ctypes.data] = 0

    def begin_tick(self, rows: np.ndarray, ref_pos: np.ndarray, ref_quat: np.ndarray, cmd_wrench: np.ndarray,
                   cmd_stiffness: np.ndarray) -> None:
        """The tick's references (steps, m, 3) and (steps, m, 4) and command (m, 6) each for ``rows``."""
        self.refs[rows, :, :3], self.refs[rows, :, 3:] = ref_pos.transpose(1, 0, 2), ref_quat.transpose(1, 0, 2)
        self.cmd_wrench[rows], self.cmd_stiffness[rows] = cmd_wrench, cmd_stiffness
        self.counter[rows], self.force_sum[rows], self.force_peak[rows] = 0.0, 0.0, 0.0

    def end_tick(self, rows: np.ndarray, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tick's touch force sum and peak (m,) each of ``rows``: the callbacks' and the last
        step's, read from the bound ``sensordata`` (n, nsensordata)."""
        force_sum, force_peak = self.force_sum[rows], self.force_peak[rows]
        add_forces(rows, sensordata, self.sensors, force_sum, force_peak)
        return force_sum, force_peak


def control_callback(model: mujoco.MjModel, offsets: tuple[int, ...]):
    """The ``callback`` for data of ``model`` whose fields sit at ``offsets`` (``data_offsets``)."""
    return callback(offsets[FIELDS.index("userdata")], model.nuserdata - CONTROL_USERDATA)


@contextlib.contextmanager
def installed(control):
    """``control`` (a ``callback``) as MuJoCo's ``mjcb_control`` inside the block, the previous
    one restored after it. The callback is one global of the process: a second batch stepping
    in another thread of it waits for the block to end."""
    with _INSTALL:  # one batch at a time steps under the process's one mjcb_control
        previous = mujoco.get_mjcb_control()
        try:
            mujoco.set_mjcb_control(control.ctypes)
            yield
        finally:
            mujoco.set_mjcb_control(previous)
