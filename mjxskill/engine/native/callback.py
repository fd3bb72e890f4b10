"""The impedance law as MuJoCo's control callback (``mjcb_control``), so that one
``Batch.step(rows, nstep=steps)`` runs a tick's control steps of every row in C: MuJoCo steps a
row's whole tick before the next row's (its data stays in the cache), and no Python runs between
two steps (benchmarks/NOTES.md sections 44 and 45).

The callback is a numba ``cfunc``. A row's ``userdata`` (the model's last ``CONTROL_USERDATA``
numbers, ``mjxskill.sim.model``) holds the address of the batch's ``ControlContext`` and the row's
index; the context holds, per row, the tick's references and command, the law's rate-limited
state, what the law reads of the step before, and the tick's touch force sums. The ``mjData``
being stepped is read through its pointer fields, whose places in the struct are found once per
engine by their values (``data_offsets``) and checked on a second ``mjData``.

What the law reads is what it reads between two ``mj_step`` calls: the state (``qpos``, ``qvel``)
now, and the site pose, ``cdof``, ``subtree_com`` and ``qfrc_bias`` of the forward pass before
(what ``mj_step`` leaves in the data, one step behind the state). Inside ``mj_step`` the data
holds the current forward pass's, so the callback keeps the previous step's in the context (its
``stash``) and uses those: whole episodes equal the per-step loop's and the numpy lockstep's bit
for bit. A step's touch force (an acceleration-stage sensor, computed after the callback) is
read by the next step's callback, the tick's last one from the bound ``sensordata`` after the
call (``ControlContext.end_tick``): the same values summed in the same order.

The callback is installed only while a batch steps (``installed``) and does nothing for data
whose ``userdata`` holds no context (a row MuJoCo reset: its ``userdata`` is zero again).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools

import mujoco
import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mjxskill._numba import compiled
from mjxskill.engine.native.kernels import SCRATCH, add_forces, impedance_law
from mjxskill.sim.controller_config import N_ARM
from mjxskill.sim.model import CONTROL_USERDATA

# the mjData pointer fields the callback reads, in the order of ``data_offsets``
FIELDS = ("qpos", "qvel", "ctrl", "site_xpos", "site_xmat", "cdof", "subtree_com", "qfrc_bias", "sensordata", "userdata")
_SCAN_WORDS = 1 << 20  # the mjData struct is ~160 kB in MuJoCo 4; the fields are found well before this

# the context's header (int64): constants, the fields' offsets, the chain, the arrays' addresses
MAGIC = 0x6D6A78736B696C6C  # "mjxskill": a header the callback trusts
_MAGIC, _ROWS, _STEPS, _SITE, _ROOT, _NSENSOR, _OFFSETS = 0, 1, 2, 3, 4, 5, 6
_CHAIN = _OFFSETS + len(FIELDS)
_ARRAYS = _CHAIN + N_ARM
ARRAYS = ("refs", "cmd_wrench", "cmd_stiffness", "nullspace_target", "torque", "stiffness", "wrench", "stash", "scratch",
          "counter", "force_sum", "force_peak", "limits", "sensors")
HEADER = _ARRAYS + len(ARRAYS)
# where in the header: each field's offset, each array's address
(_QPOS, _QVEL, _CTRL, _SITE_XPOS, _SITE_XMAT, _CDOF, _SUBTREE_COM, _QFRC_BIAS, _SENSORDATA,
 _USERDATA) = range(_OFFSETS, _OFFSETS + len(FIELDS))
(_REFS, _CMD_WRENCH, _CMD_STIFFNESS, _NULLSPACE_TARGET, _TORQUE, _STIFFNESS_STATE, _WRENCH, _STASH, _SCRATCH, _COUNTER,
 _FORCE_SUM, _FORCE_PEAK, _LIMITS, _SENSORS) = range(_ARRAYS, HEADER)
STASH = 3 + 9 + 3 + 6 * N_ARM + N_ARM  # site_xpos, site_xmat, subtree_com of the root, the arm's cdof, qfrc_bias


@intrinsic
def _f64(typingctx, address):
    """The float64 pointer at an address (an int64)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))
    return types.CPointer(types.float64)(types.int64), codegen


@intrinsic
def _i64(typingctx, address):
    """The int64 pointer at an address (an int64)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))
    return types.CPointer(types.int64)(types.int64), codegen


def data_offsets(model: mujoco.MjModel) -> tuple[int, ...]:
    """The places (in 8-byte words from the struct's start) of the ``FIELDS`` pointers in an
    ``mjData`` of ``model``, found by their values in one and checked in a second. RuntimeError
    if a field is not found or not where the second holds it (a MuJoCo whose mjData differs)."""
    first, second = mujoco.MjData(model), mujoco.MjData(model)
    by_address: dict[int, list[str]] = {}
    for name in FIELDS:  # an empty field may share its address with the next one
        by_address.setdefault(getattr(first, name).ctypes.data, []).append(name)
    found: dict[str, int] = {}
    word = 0
    while by_address and word < _SCAN_WORDS:
        for name in by_address.pop(ctypes.c_int64.from_address(first._address + 8 * word).value, []):
            found[name] = word
        word += 1
    missing = [name for name in FIELDS if name not in found]
    moved = [name for name in FIELDS if name not in missing
             and ctypes.c_int64.from_address(second._address + 8 * found[name]).value != getattr(second, name).ctypes.data]
    if missing or moved:
        raise RuntimeError(f"the native engine cannot read MuJoCo {mujoco.__version__}'s mjData: "
                           f"{', '.join(missing + moved)} not found where expected")
    return tuple(found[name] for name in FIELDS)


@compiled
def _row(address, row, width):
    """Row ``row`` (width,) of a C-contiguous (n, width) float64 array at ``address``."""
    return numba.carray(_f64(address + 8 * row * width), width)


@compiled
def control_step(d, header, row):
    """The law for one row at one control step, called by the callback inside ``mj_step`` with
    the ``mjData``'s address ``d``, the context's header address and the row's index."""
    h = numba.carray(_i64(header), HEADER)
    if h[_MAGIC] != MAGIC:
        return
    words, rows = _i64(d), h[_ROWS]
    steps, site, root, nsensor = h[_STEPS], h[_SITE], h[_ROOT], h[_NSENSOR]
    counter = numba.carray(_f64(h[_COUNTER]), rows)
    k = min(int(counter[row]), steps - 1)
    if counter[row] > 0 and nsensor > 0:  # the step before's touch force, computed after its callback
        sensordata, sensors = _f64(words[h[_SENSORDATA]]), numba.carray(_i64(h[_SENSORS]), nsensor)
        total = 0.0
        for s in sensors:
            total += sensordata[s]
        force_sum, force_peak = numba.carray(_f64(h[_FORCE_SUM]), rows), numba.carray(_f64(h[_FORCE_PEAK]), rows)
        force_sum[row] += total
        if total > force_peak[row]:
            force_peak[row] = total
    stash = _row(h[_STASH], row, STASH)
    refs = numba.carray(_f64(h[_REFS] + 8 * (row * steps + k) * 7), 7)
    limits = numba.carray(_f64(h[_LIMITS]), 12)
    qpos, qvel = numba.carray(_f64(words[h[_QPOS]]), 7), numba.carray(_f64(words[h[_QVEL]]), 7)
    impedance_law(h[_CHAIN:_CHAIN + 7], stash[0:3], stash[3:12], stash[12:15], stash[15:57].reshape((7, 6)), qpos, qvel,
                  stash[57:64], refs[0:3], refs[3:7], _row(h[_CMD_WRENCH], row, 6), _row(h[_CMD_STIFFNESS], row, 6),
                  _row(h[_NULLSPACE_TARGET], row, 7), _row(h[_TORQUE], row, 7), _row(h[_STIFFNESS_STATE], row, 6),
                  _row(h[_WRENCH], row, 6), limits[0:7], limits[7:12], numba.carray(_f64(words[h[_CTRL]]), 7),
                  _row(h[_SCRATCH], row, SCRATCH))
    # what the next step's law reads: this forward pass's, as mj_step will have left it
    site_xpos, site_xmat = _f64(words[h[_SITE_XPOS]]), _f64(words[h[_SITE_XMAT]])
    com, cdof, bias = _f64(words[h[_SUBTREE_COM]]), _f64(words[h[_CDOF]]), _f64(words[h[_QFRC_BIAS]])
    for j in range(3):
        stash[j], stash[12 + j] = site_xpos[3 * site + j], com[3 * root + j]
    for j in range(9):
        stash[3 + j] = site_xmat[9 * site + j]
    for j in range(6 * 7):
        stash[15 + j] = cdof[j]
    for j in range(7):
        stash[57 + j] = bias[j]
    counter[row] += 1.0


@functools.lru_cache(maxsize=None)
def callback(userdata_word: int, slot: int):
    """The ``cfunc`` (m, d) for data whose ``userdata`` pointer is at ``userdata_word`` of the
    struct and whose context sits at ``userdata[slot]`` (its row at ``slot + 1``). Compiled once
    per process and layout (~0.03 s: ``control_step`` comes from numba's cache); the two
    numbers are constants of it, not arguments, so no cached machine code outlives a layout."""
    @numba.cfunc(types.void(types.int64, types.int64))
    def control(m, d):
        userdata = _f64(_i64(d)[userdata_word])
        header = np.int64(userdata[slot])
        if header != 0:
            control_step(d, header, np.int64(userdata[slot + 1]))
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
        self.steps = steps
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
        """Points every row's ``userdata`` (the batch's bound (n, nuserdata) field) at this context
        and fills the stash from the bound fields after the batch's first forward pass."""
        site, root = int(self.header[_SITE]), int(self.header[_ROOT])
        userdata[:, -CONTROL_USERDATA] = float(self.header.ctypes.data)  # below 2**53: exact in a double
        userdata[:, 1 - CONTROL_USERDATA] = np.arange(len(userdata))
        self.stash[:, 0:3], self.stash[:, 3:12] = fields["site_xpos"][:, site], fields["site_xmat"][:, site]
        self.stash[:, 12:15], self.stash[:, 57:64] = fields["subtree_com"][:, root], fields["qfrc_bias"][:, :N_ARM]
        self.stash[:, 15:57] = fields["cdof"][:, :N_ARM].reshape(len(userdata), -1)

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
    one restored after it."""
    previous = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(control.ctypes)
    try:
        yield
    finally:
        mujoco.set_mjcb_control(previous)
