"""Rotation algebra: identities that a wrong sign or order would break."""

import math

import numpy as np
import pytest

from navgate.nav import rotations as r

RNG = np.random.default_rng(1)


def random_quats(n):
    q = RNG.standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_quat_product_matches_dcm_product():
    for p, q in zip(random_quats(50), random_quats(50), strict=True):
        lhs = r.quat_to_dcm(r.quat_multiply(p, q))
        assert np.allclose(lhs, r.quat_to_dcm(p) @ r.quat_to_dcm(q), atol=1e-14)


def test_quaternion_rotates_vectors_like_its_dcm():
    for q in random_quats(20):
        v = RNG.standard_normal(3)
        rotated = r.quat_multiply(r.quat_multiply(q, np.r_[0.0, v]), r.quat_conjugate(q))[1:]
        assert np.allclose(rotated, r.quat_to_dcm(q) @ v, atol=1e-14)


def test_dcm_quat_round_trip_and_orthonormality():
    for q in random_quats(100):
        c = r.quat_to_dcm(q)
        assert np.allclose(c @ c.T, np.eye(3), atol=1e-14)
        assert np.isclose(np.linalg.det(c), 1.0)
        q2 = r.dcm_to_quat(c)
        assert np.allclose(q2 * np.sign(q2[0]), q * np.sign(q[0]), atol=1e-12)


def test_euler_zyx_convention():
    # yaw 90 deg: body x (forward) points east
    c = r.euler_to_dcm(0.0, 0.0, math.pi / 2)
    assert np.allclose(c @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # pitch up 90 deg: body x points up (NED: -down)
    c = r.euler_to_dcm(0.0, math.pi / 2, 0.0)
    assert np.allclose(c @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    # roll right 90 deg: body y (right wing) points down
    c = r.euler_to_dcm(math.pi / 2, 0.0, 0.0)
    assert np.allclose(c @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    for roll, pitch, yaw in RNG.uniform([-3, -1.5, -3], [3, 1.5, 3], (50, 3)):
        assert np.allclose(r.dcm_to_euler(r.euler_to_dcm(roll, pitch, yaw)), (roll, pitch, yaw))


def test_rotvec_quaternion_exact_and_small_angle_branch():
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    for angle in (2.0, 0.3, 1e-3, 1e-7, 0.0):
        q = r.quat_from_rotvec(axis * angle)
        assert np.isclose(np.linalg.norm(q), 1.0, atol=1e-15)
        assert np.isclose(q[0], math.cos(angle / 2), atol=1e-16)
        assert np.allclose(q[1:], axis * math.sin(angle / 2), atol=1e-16)
        if angle > 0:
            assert np.allclose(r.rotvec_from_quat(q), axis * angle, rtol=1e-9, atol=1e-18)


def test_skew_is_cross_product():
    a, b = RNG.standard_normal(3), RNG.standard_normal(3)
    assert np.allclose(r.skew(a) @ b, np.cross(a, b))


def test_zero_quaternion_cannot_be_normalised():
    with pytest.raises(ValueError):
        r.quat_normalize(np.zeros(4))


def test_vectorised_forms_match_scalar_forms():
    q = random_quats(10)
    assert np.allclose(r.quat_to_dcm_array(q), np.array([r.quat_to_dcm(x) for x in q]))
    ang = RNG.uniform(-1, 1, (3, 10))
    c = r.euler_to_dcm_array(*ang)
    assert np.allclose(c, np.array([r.euler_to_dcm(*a) for a in ang.T]))
    assert np.allclose(np.array(r.dcm_to_euler_array(c)), ang)


def test_dcm_to_quat_array_equals_the_scalar_form_in_every_branch():
    """The vectorised Shepperd method takes the scalar one's branch and arithmetic per row:
    equal bit for bit, including the three trace-negative branches (180-degree turns)."""
    c = r.quat_to_dcm_array(random_quats(2000))
    c = np.concatenate([c, [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]),
                            np.diag([-1.0, -1, 1])]])
    got = r.dcm_to_quat_array(c)
    want = np.array([r.dcm_to_quat(m) for m in c])
    assert np.array_equal(got, want)
    assert np.all(got[:, 0] >= 0.0)
