"""Rotation algebra: Hamilton scalar-first quaternions, direction cosine matrices, Euler angles.

Conventions (docs/conventions.md):

- A quaternion ``q = [q0, q1, q2, q3]`` (scalar first, Hamilton product) represents the
  attitude of the body (FRD) frame relative to the navigation (NED) frame; it maps body
  vectors into the navigation frame, ``v_n = q (x) v_b (x) q*``, and its matrix is ``C_b^n``.
- ``quat_to_dcm`` is the form seed 000 writes (q0^2+q1^2-q2^2-q3^2 on the diagonal); it is
  exact for unit quaternions only (the seeds README notes seed 003 uses the 1-2(..) form).
- Euler angles are the aerospace ZYX sequence: yaw about down, then pitch, then roll;
  ``C_b^n = Rz(yaw) Ry(pitch) Rx(roll)``.
- A rotation vector ``theta`` (axis times angle) maps to the quaternion
  ``[cos(|theta|/2), sin(|theta|/2) theta/|theta|]``; below a small angle the series
  ``[1 - |theta|^2/8, theta/2 (1 - |theta|^2/24)]`` is used (seed 000 "small-angle branch").

Reference: Groves (2013), Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems, 2nd ed., appendix E; Savage (2000), Strapdown Analytics, ch. 3.

Every function is compiled with Numba (``cache=True``) so that the strapdown and filter
loops can call it; they are equally callable from plain Python with NumPy arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: below this rotation angle (rad) the delta quaternion uses its Taylor series;
#: the series' first omitted terms are O(theta^4/384), far below float64 resolution here.
SMALL_ANGLE_RAD = 1e-6


@njit(cache=True)
def skew(v):
    """The cross-product matrix [v x], such that skew(a) @ b == cross(a, b)."""
    m = np.zeros((3, 3))
    m[0, 1] = -v[2]
    m[0, 2] = v[1]
    m[1, 0] = v[2]
    m[1, 2] = -v[0]
    m[2, 0] = -v[1]
    m[2, 1] = v[0]
    return m


@njit(cache=True)
def quat_multiply(p, q):
    """Hamilton product p (x) q (seed 000 'Quaternion multiplication')."""
    r = np.empty(4)
    r[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    r[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    r[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    r[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]
    return r


@njit(cache=True)
def quat_conjugate(q):
    """Conjugate (the inverse of a unit quaternion)."""
    return np.array([q[0], -q[1], -q[2], -q[3]])


@njit(cache=True)
def quat_normalize(q):
    """q / |q|; raises ValueError for a zero or non-finite quaternion."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if not (n > 0.0) or not math.isfinite(n):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    return q / n


@njit(cache=True)
def quat_from_rotvec(theta):
    """Quaternion of the rotation vector theta (rad), with the small-angle branch."""
    angle2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    angle = math.sqrt(angle2)
    q = np.empty(4)
    if angle < SMALL_ANGLE_RAD:
        q[0] = 1.0 - angle2 / 8.0
        s = 0.5 - angle2 / 48.0
    else:
        q[0] = math.cos(0.5 * angle)
        s = math.sin(0.5 * angle) / angle
    q[1] = s * theta[0]
    q[2] = s * theta[1]
    q[3] = s * theta[2]
    return q


@njit(cache=True)
def rotvec_from_quat(q):
    """Rotation vector (rad) of a unit quaternion, angle in [0, pi]."""
    w = q[0]
    v = q[1:4].copy()
    if w < 0.0:
        w = -w
        v = -v
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if s < 1e-12:
        return 2.0 * v / w
    angle = 2.0 * math.atan2(s, w)
    return v * (angle / s)


@njit(cache=True, inline="always")
def dcm_from_quat_into(q0, q1, q2, q3, c):
    """Write C_b^n of the unit quaternion (q0, q1, q2, q3) into the 3x3 array ``c``.

    Seed 000's q0^2+q1^2-q2^2-q3^2 form; the allocation-free kernel the strapdown loop uses.
    """
    c[0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c[0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    c[0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    c[1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    c[1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c[1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    c[2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    c[2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    c[2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3


@njit(cache=True)
def quat_to_dcm(q):
    """C_b^n of a unit quaternion, in seed 000's q0^2+q1^2-q2^2-q3^2 form."""
    c = np.empty((3, 3))
    dcm_from_quat_into(q[0], q[1], q[2], q[3], c)
    return c


@njit(cache=True)
def dcm_to_quat(c):
    """Unit quaternion (q0 >= 0) of a rotation matrix, by Shepperd's method."""
    tr = c[0, 0] + c[1, 1] + c[2, 2]
    q = np.empty(4)
    if tr > max(c[0, 0], c[1, 1], c[2, 2]):
        s = 2.0 * math.sqrt(1.0 + tr)
        q[0] = 0.25 * s
        q[1] = (c[2, 1] - c[1, 2]) / s
        q[2] = (c[0, 2] - c[2, 0]) / s
        q[3] = (c[1, 0] - c[0, 1]) / s
    elif c[0, 0] >= c[1, 1] and c[0, 0] >= c[2, 2]:
        s = 2.0 * math.sqrt(1.0 + c[0, 0] - c[1, 1] - c[2, 2])
        q[0] = (c[2, 1] - c[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (c[0, 1] + c[1, 0]) / s
        q[3] = (c[0, 2] + c[2, 0]) / s
    elif c[1, 1] >= c[2, 2]:
        s = 2.0 * math.sqrt(1.0 + c[1, 1] - c[0, 0] - c[2, 2])
        q[0] = (c[0, 2] - c[2, 0]) / s
        q[1] = (c[0, 1] + c[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (c[1, 2] + c[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + c[2, 2] - c[0, 0] - c[1, 1])
        q[0] = (c[1, 0] - c[0, 1]) / s
        q[1] = (c[0, 2] + c[2, 0]) / s
        q[2] = (c[1, 2] + c[2, 1]) / s
        q[3] = 0.25 * s
    if q[0] < 0.0:
        q = -q
    return q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


@njit(cache=True)
def euler_to_dcm(roll, pitch, yaw):
    """C_b^n = Rz(yaw) Ry(pitch) Rx(roll) (aerospace ZYX), angles in rad."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    c = np.empty((3, 3))
    c[0, 0] = cp * cy
    c[0, 1] = sr * sp * cy - cr * sy
    c[0, 2] = cr * sp * cy + sr * sy
    c[1, 0] = cp * sy
    c[1, 1] = sr * sp * sy + cr * cy
    c[1, 2] = cr * sp * sy - sr * cy
    c[2, 0] = -sp
    c[2, 1] = sr * cp
    c[2, 2] = cr * cp
    return c


@njit(cache=True)
def dcm_to_euler(c):
    """(roll, pitch, yaw) in rad from C_b^n; yaw in (-pi, pi]."""
    pitch = -math.asin(min(1.0, max(-1.0, c[2, 0])))
    roll = math.atan2(c[2, 1], c[2, 2])
    yaw = math.atan2(c[1, 0], c[0, 0])
    return roll, pitch, yaw


@njit(cache=True)
def euler_to_quat(roll, pitch, yaw):
    """Quaternion of ZYX Euler angles (rad)."""
    return dcm_to_quat(euler_to_dcm(roll, pitch, yaw))


@njit(cache=True)
def quat_to_euler(q):
    """ZYX Euler angles (rad) of a unit quaternion."""
    return dcm_to_euler(quat_to_dcm(q))


def euler_to_dcm_array(roll, pitch, yaw):
    """Vectorised euler_to_dcm: arrays of N angles -> (N, 3, 3) matrices."""
    roll, pitch, yaw = np.broadcast_arrays(
        np.asarray(roll, float), np.asarray(pitch, float), np.asarray(yaw, float))
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    c = np.empty(roll.shape + (3, 3))
    c[..., 0, 0] = cp * cy
    c[..., 0, 1] = sr * sp * cy - cr * sy
    c[..., 0, 2] = cr * sp * cy + sr * sy
    c[..., 1, 0] = cp * sy
    c[..., 1, 1] = sr * sp * sy + cr * cy
    c[..., 1, 2] = cr * sp * sy - sr * cy
    c[..., 2, 0] = -sp
    c[..., 2, 1] = sr * cp
    c[..., 2, 2] = cr * cp
    return c


def dcm_to_euler_array(c):
    """Vectorised dcm_to_euler: (N, 3, 3) -> (roll, pitch, yaw) arrays."""
    c = np.asarray(c, float)
    pitch = -np.arcsin(np.clip(c[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return roll, pitch, yaw


def quat_to_dcm_array(q):
    """Vectorised quat_to_dcm: (N, 4) -> (N, 3, 3)."""
    q = np.asarray(q, float)
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    c = np.empty(q.shape[:-1] + (3, 3))
    c[..., 0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c[..., 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    c[..., 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    c[..., 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    c[..., 1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c[..., 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    c[..., 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    c[..., 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    c[..., 2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return c


def dcm_to_quat_array(c):
    """Vectorised dcm_to_quat (N, 3, 3) -> (N, 4), q0 >= 0: Shepperd's method with the same
    branch choice and the same arithmetic per element as :func:`dcm_to_quat`."""
    c = np.asarray(c, float).reshape(-1, 3, 3)
    c00, c01, c02 = c[:, 0, 0], c[:, 0, 1], c[:, 0, 2]
    c10, c11, c12 = c[:, 1, 0], c[:, 1, 1], c[:, 1, 2]
    c20, c21, c22 = c[:, 2, 0], c[:, 2, 1], c[:, 2, 2]
    tr = c00 + c11 + c22
    b0 = tr > np.maximum(np.maximum(c00, c11), c22)
    b1 = ~b0 & (c00 >= c11) & (c00 >= c22)
    b2 = ~b0 & ~b1 & (c11 >= c22)
    b3 = ~(b0 | b1 | b2)
    out = np.empty((c.shape[0], 4))
    with np.errstate(invalid="ignore", divide="ignore"):  # the branches not taken
        for mask, diag, rows in (
                (b0, 1.0 + tr, ((None, c21 - c12, c02 - c20, c10 - c01), 0)),
                (b1, 1.0 + c00 - c11 - c22, ((c21 - c12, None, c01 + c10, c02 + c20), 1)),
                (b2, 1.0 + c11 - c00 - c22, ((c02 - c20, c01 + c10, None, c12 + c21), 2)),
                (b3, 1.0 + c22 - c00 - c11, ((c10 - c01, c02 + c20, c12 + c21, None), 3))):
            if not mask.any():
                continue
            s = 2.0 * np.sqrt(diag[mask])
            num, big = rows
            for j in range(4):
                out[mask, j] = 0.25 * s if j == big else num[j][mask] / s
    out[out[:, 0] < 0.0] *= -1.0
    norm = np.sqrt(out[:, 0] * out[:, 0] + out[:, 1] * out[:, 1] + out[:, 2] * out[:, 2]
                   + out[:, 3] * out[:, 3])
    return out / norm[:, None]
