"""The impedance law of ``mjxskill.engine.native_reference.batched_impedance_control`` compiled
with numba: for one arm (``impedance_law``, what the control callback runs inside ``mj_step``)
and as one loop over the rows of a ``mujoco.batch.Batch`` (``impedance_rows``).

Why numba: the law is ~40 small operations on 6x7 matrices per arm; as numpy over 42 rows it
costs ~350 us per control step (one call per quantity, each ~5 us of dispatch), six times the
physics it controls (benchmarks/NOTES.md sections 7-11 and 15). A compiled loop does the same
arithmetic in a few microseconds; JAX's CPU dispatch (~20 us per call, and a copy of every bound
array into its buffers) would cost more than the arithmetic. Cython would need a compiler at
install time; numba ships wheels.

The law reads what ``mj_step`` leaves of a step (in the batch's bound fields, or, inside
``mj_step``, the control callback's stash of the step before), exactly what the numpy law reads
from each ``MjData``: the Jacobian is assembled from ``cdof`` and ``subtree_com`` as
``mj_jac`` does (the site's point offset from its tree's centre of mass crossed with each
ancestor dof's motion axis), the site orientation converted as ``mju_mat2Quat`` does, the
rotation error as ``mju_quat2Vel``. The order of operations differs from numpy's BLAS and LAPACK
calls (the damped pseudo-inverse is never formed: J J^T + lambda I is symmetric positive
definite, and its Cholesky factor solves for the one vector the nullspace term needs), so
results agree to rounding, not bit for bit; the tests bound the difference on
whole episodes (1e-9 on reward totals, equal discrete outcomes). No fastmath: rows never mix
and the result of a row does not depend on the others or on the thread it runs on.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mjxskill._numba import compiled as _compiled
from mjxskill.sim.controller_config import N_ARM


@_compiled
def _mat2quat(mat, quat):
    """``mju_mat2Quat`` operation for operation: the branch of the largest quaternion component,
    then ``mju_normalize4`` (which leaves a norm within 1e-15 of 1 alone)."""
    if mat[0] + mat[4] + mat[8] > 0.0:
        quat[0] = 0.5 * math.sqrt(1.0 + mat[0] + mat[4] + mat[8])
        quat[1] = 0.25 * (mat[7] - mat[5]) / quat[0]
        quat[2] = 0.25 * (mat[2] - mat[6]) / quat[0]
        quat[3] = 0.25 * (mat[3] - mat[1]) / quat[0]
    elif mat[0] > mat[4] and mat[0] > mat[8]:
        quat[1] = 0.5 * math.sqrt(1.0 + mat[0] - mat[4] - mat[8])
        quat[0] = 0.25 * (mat[7] - mat[5]) / quat[1]
        quat[2] = 0.25 * (mat[1] + mat[3]) / quat[1]
        quat[3] = 0.25 * (mat[2] + mat[6]) / quat[1]
    elif mat[4] > mat[8]:
        quat[2] = 0.5 * math.sqrt(1.0 - mat[0] + mat[4] - mat[8])
        quat[0] = 0.25 * (mat[2] - mat[6]) / quat[2]
        quat[1] = 0.25 * (mat[1] + mat[3]) / quat[2]
        quat[3] = 0.25 * (mat[5] + mat[7]) / quat[2]
    else:
        quat[3] = 0.5 * math.sqrt(1.0 - mat[0] - mat[4] + mat[8])
        quat[0] = 0.25 * (mat[3] - mat[1]) / quat[3]
        quat[1] = 0.25 * (mat[2] + mat[6]) / quat[3]
        quat[2] = 0.25 * (mat[5] + mat[7]) / quat[3]
    norm = math.sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    if norm < 1e-15:  # mjMINVAL
        quat[0], quat[1], quat[2], quat[3] = 1.0, 0.0, 0.0, 0.0
    elif abs(norm - 1.0) > 1e-15:
        inverse = 1.0 / norm
        for k in range(4):
            quat[k] *= inverse


@_compiled
def _rate_limit(previous, target, max_delta):
    step = target - previous
    if step > max_delta:
        step = max_delta
    elif step < -max_delta:
        step = -max_delta
    return previous + step


@_compiled
def _site_jacobian(chain, cdof, com, site_pos, jac):
    """The site Jacobian (6, 7) as ``mj_jac``: translation rows cross(axis, offset) plus the
    dof's linear part, the offset taken from the site's tree's centre of mass ``com`` (3,);
    cdof (>= 7, 6): the arm's dofs' motion axes."""
    ox, oy, oz = site_pos[0] - com[0], site_pos[1] - com[1], site_pos[2] - com[2]
    for j in range(7):
        if chain[j]:
            a0, a1, a2 = cdof[j, 0], cdof[j, 1], cdof[j, 2]
            jac[0, j] = (a1 * oz - a2 * oy) + cdof[j, 3]
            jac[1, j] = (a2 * ox - a0 * oz) + cdof[j, 4]
            jac[2, j] = (a0 * oy - a1 * ox) + cdof[j, 5]
            jac[3, j], jac[4, j], jac[5, j] = a0, a1, a2
        else:
            for k in range(6):
                jac[k, j] = 0.0


@_compiled
def _pose_error(position, mat, ref_pos, ref_quat, quat, pose_err):
    """Position error and ``quat2vel(quat * conj(ref))`` (the angle wrapped into (-pi, pi])."""
    _mat2quat(mat, quat)
    bw, bx, by, bz = ref_quat[0], -ref_quat[1], -ref_quat[2], -ref_quat[3]
    aw, ax, ay, az = quat[0], quat[1], quat[2], quat[3]
    ew = aw * bw - ax * bx - ay * by - az * bz
    ex = aw * bx + ax * bw + ay * bz - az * by
    ey = aw * by - ax * bz + ay * bw + az * bx
    ez = aw * bz + ax * by - ay * bx + az * bw
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    angle = 2.0 * math.atan2(norm, ew)
    if angle > math.pi:
        angle -= 2.0 * math.pi
    for k in range(3):
        pose_err[k] = position[k] - ref_pos[k]
    if norm < 1e-15:  # mjMINVAL: MuJoCo's x axis
        pose_err[3], pose_err[4], pose_err[5] = 1.0 * angle, 0.0 * angle, 0.0 * angle
    else:
        pose_err[3], pose_err[4], pose_err[5] = ex / norm * angle, ey / norm * angle, ez / norm * angle


@_compiled
def _damped_solve(jac, damping, chol, b):
    """b <- (J J^T + lambda I)^-1 b, b (6,), J (6, 7): through the Cholesky factor of the
    symmetric positive definite J J^T + lambda I, built row by row in ``chol``'s lower triangle,
    then one forward and one back substitution (the law needs the damped pseudo-inverse only
    applied to one vector, never the (6, 7) matrix itself)."""
    for a in range(6):
        for c in range(a + 1):
            acc = jac[a, 0] * jac[c, 0]
            for j in range(1, 7):
                acc += jac[a, j] * jac[c, j]
            acc = acc + (damping if a == c else 0.0)
            for e in range(c):
                acc -= chol[a, e] * chol[c, e]
            chol[a, c] = math.sqrt(acc) if a == c else acc / chol[c, c]
    for a in range(6):
        acc = b[a]
        for c in range(a):
            acc -= chol[a, c] * b[c]
        b[a] = acc / chol[a, a]
    for a in range(5, -1, -1):
        acc = b[a]
        for c in range(a + 1, 6):
            acc -= chol[c, a] * b[c]
        b[a] = acc / chol[a, a]


@_compiled
def impedance_law(chain, site_pos, site_mat, com, cdof, qpos, qvel, qfrc_bias, ref_pos, ref_quat, cmd_wrench,
                  cmd_stiffness, nullspace_target, torque, stiffness, wrench, torque_limit, rates, ctrl, scratch):
    """The impedance law of one arm at one control step. What ``mj_step`` left of the step
    before: site_pos (3,) and site_mat (9,) of the site, com (3,) its tree's centre of mass, cdof
    (>= 7, 6), qfrc_bias (>= 7,); the state now: qpos, qvel (>= 7,). ref_pos (3,), ref_quat
    (4,), cmd_wrench and cmd_stiffness (6,), nullspace_target (7,): the command. torque (7,),
    stiffness and wrench (6,): the rate-limited state, updated in place. torque_limit (7,);
    rates: (stiffness step, wrench step, torque step, pinv damping, nullspace stiffness).
    Writes the torques into ctrl[:7]; scratch (>= SCRATCH,): working memory."""
    stiffness_step, wrench_step, torque_step, damping, k_ns = rates[0], rates[1], rates[2], rates[3], rates[4]
    jac, chol = scratch[0:42].reshape((6, 7)), scratch[42:78].reshape((6, 6))
    quat, pose_err, force, drive, x_drive = scratch[78:82], scratch[82:88], scratch[88:94], scratch[94:101], \
        scratch[101:107]
    damping_ns = 2.0 * math.sqrt(k_ns)
    for k in range(6):
        stiffness[k] = _rate_limit(stiffness[k], cmd_stiffness[k], stiffness_step)
        wrench[k] = _rate_limit(wrench[k], cmd_wrench[k], wrench_step)
    _site_jacobian(chain, cdof, com, site_pos, jac)
    _pose_error(site_pos, site_mat, ref_pos, ref_quat, quat, pose_err)
    for k in range(6):  # task-space force: spring, critical damping on the twist, the wrench
        twist = jac[k, 0] * qvel[0]
        for j in range(1, 7):
            twist += jac[k, j] * qvel[j]
        s = stiffness[k]
        force[k] = -s * pose_err[k] - 2.0 * math.sqrt(max(s, 0.0)) * twist + wrench[k]
    for j in range(7):
        drive[j] = k_ns * (nullspace_target[j] - qpos[j]) - damping_ns * qvel[j]
    # (I - J^T x) drive = drive - J^T (x drive), x = (J J^T + lambda I)^-1 J: x drive is one
    # damped solve of J drive
    for a in range(6):
        acc = jac[a, 0] * drive[0]
        for c in range(1, 7):
            acc += jac[a, c] * drive[c]
        x_drive[a] = acc
    _damped_solve(jac, damping, chol, x_drive)
    for j in range(7):  # bias + (I - J^T x) drive + J^T force, rate- and torque-limited
        proj = jac[0, j] * x_drive[0]
        for a in range(1, 6):
            proj += jac[a, j] * x_drive[a]
        tau = qfrc_bias[j] + (drive[j] - proj)
        for k in range(6):
            tau += jac[k, j] * force[k]
        tau = _rate_limit(torque[j], tau, torque_step)
        tau = min(max(tau, -torque_limit[j]), torque_limit[j])
        torque[j] = tau
        ctrl[j] = tau


SCRATCH = 107  # doubles of working memory ``impedance_law`` needs


@_compiled
def impedance_rows(rows, chain, site, root, cdof, subtree_com, site_xpos, site_xmat, qpos, qvel, qfrc_bias,
                   ref_pos, ref_quat, cmd_wrench, cmd_stiffness, nullspace_target, torque, stiffness, wrench,
                   torque_limit, rates, ctrl):
    """``impedance_law`` for the batch rows ``rows`` (m,) at one control step, from the batch's
    bound fields after ``mj_step``: cdof (n, nv, 6), subtree_com (n, nbody, 3), site_xpos
    (n, nsite, 3), site_xmat (n, nsite, 9), qpos (n, nq), qvel and qfrc_bias (n, nv); chain (7,)
    bool: which of the arm's dofs are ancestors of the site's body (``mj_jac``'s chain); site,
    root: the site id and its body's tree root. ref_pos (m, 3), ref_quat (m, 4), cmd_wrench and
    cmd_stiffness (m, 6), nullspace_target (m, 7), torque (m, 7), stiffness and wrench (m, 6):
    per row of ``rows``, as ``impedance_law``'s. Writes each row's torques into ctrl (n, nu)."""
    scratch = np.empty(SCRATCH)
    for r in range(rows.shape[0]):
        i = rows[r]
        impedance_law(chain, site_xpos[i, site], site_xmat[i, site], subtree_com[i, root], cdof[i], qpos[i], qvel[i],
                      qfrc_bias[i], ref_pos[r], ref_quat[r], cmd_wrench[r], cmd_stiffness[r], nullspace_target[r],
                      torque[r], stiffness[r], wrench[r], torque_limit, rates, ctrl[i], scratch)


@_compiled
def site_quats(rows, site, site_xmat, quats):
    """The orientation of ``site`` in each row of ``rows`` as ``mju_mat2Quat`` gives it, into
    quats (m, 4) (a tick's end reads the tool's pose of every row at once)."""
    for r in range(rows.shape[0]):
        _mat2quat(site_xmat[rows[r], site], quats[r])


@_compiled
def add_forces(rows, sensordata, sensors, force_sum, force_peak):
    """This step's contact force per row of ``rows``: the sum of the tool's touch ``sensors``,
    added to force_sum and folded into force_peak (m,), in place."""
    for r in range(rows.shape[0]):
        total = 0.0
        for s in sensors:
            total += sensordata[rows[r], s]
        force_sum[r] += total
        if total > force_peak[r]:
            force_peak[r] = total


@_compiled
def _trapezoid(t, distance, duration, speed, acc, dec):
    """``motion.trapezoid_position``: the distance travelled at time t, clamped to [0, duration]."""
    t_acc, t_dec = speed / acc, speed / dec
    t = min(max(t, 0.0), duration)
    if t < t_acc:
        return 0.5 * acc * t * t
    if t < duration - t_dec:
        return 0.5 * acc * t_acc * t_acc + speed * (t - t_acc)
    return distance - 0.5 * dec * (duration - t) * (duration - t)


@_compiled
def motion_references(rows, t, pos, quat):
    """The references of N straight-line motions (their ``motion.LinearMotion.row``, stacked
    (N, 22), its columns in ``motion``'s order) at times t (n, N), one column per motion, into pos (n, N, 3) and quat (n, N, 4):
    ``LinearMotion.at``'s arithmetic (the trapezoids, the rotation vector's quaternion applied to
    the start orientation), in a compiled loop (numpy's ~30 calls a tick cost more than the
    arithmetic of a batch's rows)."""
    for r in range(rows.shape[0]):
        length, angle, duration = rows[r, 13], rows[r, 14], rows[r, 15]
        for k in range(t.shape[0]):
            frac_pos = _trapezoid(t[k, r], length, duration, rows[r, 16], rows[r, 18], rows[r, 19]) / length \
                if length > 0 else 1.0
            frac_rot = _trapezoid(t[k, r], angle, duration, rows[r, 17], rows[r, 20], rows[r, 21]) / angle \
                if angle > 0 else 1.0
            for i in range(3):
                pos[k, r, i] = rows[r, i] + frac_pos * rows[r, 7 + i]
            v0, v1, v2 = frac_rot * rows[r, 10], frac_rot * rows[r, 11], frac_rot * rows[r, 12]
            turned = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)  # rotations.rotvec_to_quat
            scale = 0.5 if turned < 1e-9 else math.sin(0.5 * turned) / turned
            aw, ax, ay, az = math.cos(0.5 * turned), v0 * scale, v1 * scale, v2 * scale
            bw, bx, by, bz = rows[r, 3], rows[r, 4], rows[r, 5], rows[r, 6]
            quat[k, r, 0] = aw * bw - ax * bx - ay * by - az * bz
            quat[k, r, 1] = aw * bx + ax * bw + ay * bz - az * by
            quat[k, r, 2] = aw * by - ax * bz + ay * bw + az * bx
            quat[k, r, 3] = aw * bz + ax * by - ay * bx + az * bw


@_compiled
def spiral_rows(theta, radius, params, axes, dt, pos, end_pos):
    """The search spirals of m rows over a tick's n control periods: each period's offset added
    to pos (n, m, 3), theta and radius (m,) advanced past them in place (``motion.spiral_step``
    each period), and the offset at the end (the next reference's) added to end_pos (m, 3);
    params (m, 3): radius cap, path velocity, pitch; axes (m, 2, 3): the spiral's plane. The
    same scalar operations in the same order as the plain loop's ``spiral_step`` and
    ``blackboard.spiralled``, so the same values."""
    for r in range(theta.shape[0]):
        th, rad = theta[r], radius[r]
        radius_max, velocity, pitch = params[r, 0], params[r, 1], params[r, 2]
        for k in range(pos.shape[0]):
            c, s = math.cos(th), math.sin(th)
            for i in range(3):
                pos[k, r, i] = pos[k, r, i] + rad * (c * axes[r, 0, i] + s * axes[r, 1, i])
            dtheta = velocity / (rad + 0.001) * dt
            th = th + dtheta
            rad = min(rad + dtheta * pitch / (2.0 * math.pi), radius_max)
        c, s = math.cos(th), math.sin(th)
        for i in range(3):
            end_pos[r, i] = end_pos[r, i] + rad * (c * axes[r, 0, i] + s * axes[r, 1, i])
        theta[r], radius[r] = th, rad


# -- the law inside mj_step: what ``mjxskill.engine.native.callback`` runs for a row ----------------
# Here, beside the law, so that numba's cache of ``control_step`` is invalidated with this file.

# the mjData pointer fields the callback reads, in the order of ``data_offsets``
FIELDS = ("qpos", "qvel", "ctrl", "site_xpos", "site_xmat", "cdof", "subtree_com", "qfrc_bias", "sensordata", "userdata")

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


@_compiled
def keep_kinematics(stash, site_pos, site_mat, com, cdof, bias):
    """What the next step's law reads, kept in a row's stash (STASH,): the site's position (3,)
    and orientation matrix (9,), its tree's centre of mass (3,), the arm's cdof (>= 42, flat)
    and bias forces (>= 7,); ``control_step`` reads them back in this layout."""
    for j in range(3):
        stash[j], stash[12 + j] = site_pos[j], com[j]
    for j in range(9):
        stash[3 + j] = site_mat[j]
    for j in range(6 * N_ARM):
        stash[15 + j] = cdof[j]
    for j in range(N_ARM):
        stash[57 + j] = bias[j]


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


@_compiled
def _row(address, row, width):
    """Row ``row`` (width,) of a C-contiguous (n, width) float64 array at ``address``."""
    return numba.carray(_f64(address + 8 * row * width), width)


@_compiled
def control_step(d, header, row):
    """The law for one row at one control step, called by the callback inside ``mj_step`` with
    the ``mjData``'s address ``d``, the context's header address and the row's index."""
    h = numba.carray(_i64(header), HEADER)
    words, rows = _i64(d), h[_ROWS]
    if h[_MAGIC] != MAGIC or row < 0 or row >= rows:
        return
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
    keep_kinematics(stash, numba.carray(_f64(words[h[_SITE_XPOS]] + 8 * 3 * site), 3),
                    numba.carray(_f64(words[h[_SITE_XMAT]] + 8 * 9 * site), 9),
                    numba.carray(_f64(words[h[_SUBTREE_COM]] + 8 * 3 * root), 3),
                    numba.carray(_f64(words[h[_CDOF]]), 6 * N_ARM), numba.carray(_f64(words[h[_QFRC_BIAS]]), N_ARM))
    counter[row] += 1.0
