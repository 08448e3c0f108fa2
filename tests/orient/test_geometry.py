"""Lead/tilt postures (orient.geometry): conventions of docs/method.md section 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from orient.geometry import (
    Posture,
    inclination,
    lead_tilt_of,
    local_frame,
    posture_axis,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)
vectors = st.tuples(finite, finite, finite).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 0.1)


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation of v about the unit axis (right-handed), independent of orient."""
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * (axis @ v) * (1 - math.cos(angle)))


def _frame_inputs(normal: np.ndarray, feed: np.ndarray) -> bool:
    n = normal / np.linalg.norm(normal)
    f = feed - (feed @ n) * n
    return np.linalg.norm(f) > 0.1 * np.linalg.norm(feed)


@given(vectors, vectors)
def test_local_frame_is_right_handed_and_orthonormal(normal, feed):
    if not _frame_inputs(normal, feed):
        return
    f, b, n = local_frame(normal, feed)
    M = np.vstack([f, b, n])
    np.testing.assert_allclose(M @ M.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.cross(f, b), n, atol=1e-12)
    np.testing.assert_allclose(n, normal / np.linalg.norm(normal), atol=1e-12)
    assert f @ feed > 0  # f is the feed projected, not reversed


@given(vectors, vectors, st.floats(-1.5, 1.5), st.floats(-3.1, 3.1))
def test_axis_is_the_normal_rotated_about_b_then_f(normal, feed, lead, tilt):
    """u = R_f(tilt) R_b(lead) n, the rotations about the fixed local axes."""
    if not _frame_inputs(normal, feed):
        return
    f, b, n = local_frame(normal, feed)
    expected = _rotate(_rotate(n, b, lead), f, tilt)
    np.testing.assert_allclose(posture_axis(normal, feed, lead, tilt), expected, atol=1e-12)


@given(vectors, vectors, st.floats(-1.55, 1.55), st.floats(-3.1, 3.1))
def test_round_trip_axis_lead_tilt_axis(normal, feed, lead, tilt):
    if not _frame_inputs(normal, feed):
        return
    u = posture_axis(normal, feed, lead, tilt)
    lead2, tilt2 = lead_tilt_of(u, normal, feed)
    np.testing.assert_allclose(posture_axis(normal, feed, lead2, tilt2), u, atol=1e-9)
    assert lead2 == pytest.approx(lead, abs=1e-7)
    if math.cos(lead) > 1e-3:  # tilt is undefined with the axis along the feed
        assert math.remainder(float(tilt2) - tilt, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


@given(vectors, vectors, st.floats(0.01, 1.5), st.floats(-1.5, 1.5))
def test_sign_conventions(normal, feed, lead, tilt):
    """Positive lead leans the axis toward +f; positive tilt toward -b."""
    if not _frame_inputs(normal, feed):
        return
    f, b, _ = local_frame(normal, feed)
    u = posture_axis(normal, feed, lead, 0.0)
    assert u @ f > 0 and u @ b == pytest.approx(0.0, abs=1e-12)
    if abs(tilt) > 0.01:
        u = posture_axis(normal, feed, 0.0, tilt)
        assert math.copysign(1.0, -(u @ b)) == math.copysign(1.0, tilt)
        assert u @ f == pytest.approx(0.0, abs=1e-12)


def test_flat_floor_example_and_inclination():
    """Feed +X on a floor (normal +Z): b = +Y; lead 30 deg leans toward +X."""
    n, feed = np.array([0.0, 0.0, 1.0]), np.array([2.0, 0.0, 0.5])
    f, b, _ = local_frame(n, feed)
    np.testing.assert_allclose(f, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(b, [0, 1, 0], atol=1e-15)
    u = posture_axis(n, feed, math.radians(30), 0.0)
    np.testing.assert_allclose(u, [0.5, 0.0, math.sqrt(3) / 2], atol=1e-15)
    u = posture_axis(n, feed, 0.0, math.radians(30))
    np.testing.assert_allclose(u, [0.0, -0.5, math.sqrt(3) / 2], atol=1e-15)
    lead, tilt = math.radians(20), math.radians(-35)
    u = posture_axis(n, feed, lead, tilt)
    assert float(inclination(u, n)) == pytest.approx(math.acos(math.cos(lead) * math.cos(tilt)),
                                                     abs=1e-12)


def test_broadcasting_many_postures_at_many_points():
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(4, 1, 3))
    feeds = rng.normal(size=(4, 1, 3))
    lead = np.radians(np.linspace(-30, 30, 5))
    tilt = np.radians(np.linspace(-20, 20, 5))
    u = posture_axis(normals, feeds, lead, tilt)
    assert u.shape == (4, 5, 3)
    np.testing.assert_allclose(np.linalg.norm(u, axis=-1), 1.0, atol=1e-12)
    for i in range(4):
        for k in range(5):
            np.testing.assert_allclose(
                u[i, k], posture_axis(normals[i, 0], feeds[i, 0], lead[k], tilt[k]), atol=1e-14)
    grid = posture_axis(normals[0, 0], feeds[0, 0], *np.meshgrid(lead, tilt, indexing="ij"))
    assert grid.shape == (5, 5, 3)
    l2, t2 = lead_tilt_of(grid, normals[0, 0], feeds[0, 0])
    np.testing.assert_allclose(l2, np.meshgrid(lead, tilt, indexing="ij")[0], atol=1e-12)
    np.testing.assert_allclose(t2, np.meshgrid(lead, tilt, indexing="ij")[1], atol=1e-12)


def test_posture_dataclass():
    p = Posture.from_deg(10.0, -5.0)
    assert p.lead_rad == pytest.approx(math.radians(10.0))
    assert p.tilt_deg == pytest.approx(-5.0)
    n, f = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(p.axis(n, f), posture_axis(n, f, p.lead_rad, p.tilt_rad))
    with pytest.raises(AttributeError):
        p.lead_rad = 0.0  # frozen
    with pytest.raises(ValueError, match="lead_deg"):
        Posture.from_deg(math.nan, 0.0)
    with pytest.raises(ValueError, match="lead_rad"):
        Posture(math.pi / 2, 0.0)


def test_refuses_bad_input():
    n = np.array([0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="feed"):
        local_frame(n, [0.0, 0.0, 3.0])
    with pytest.raises(ValueError, match="normal"):
        local_frame([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="normal"):
        local_frame([0.0, math.nan, 1.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="tilt_rad"):
        posture_axis(n, [1.0, 0.0, 0.0], 0.0, math.inf)
    with pytest.raises(ValueError, match="axis"):
        inclination([0.0, 0.0, 0.0], n)
