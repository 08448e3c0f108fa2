"""The one-frame closed form against the vectorised frames."""

import numpy as np

from errpred.frames import tool_frame, tool_frames


def test_tool_frame_is_tool_frames_to_the_bit():
    rng = np.random.default_rng(7)
    cases = []
    for _ in range(3000):
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        cases.append((u, rng.standard_normal(3) * rng.uniform(1e-3, 1e3)))
    for _ in range(200):
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        cases.append((u, u * rng.uniform(-3.0, 3.0)))  # a plunge: feed along the axis
    cases += [(np.array([0.0, 0.0, 1.0]), np.zeros(3)),  # no feed
              (np.array([1.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])),  # X along the axis
              (np.array([0.0, 0.0, 1.0]), np.array([1e-12, 0.0, 5.0]))]
    for u, f in cases:
        for sign in (1, -1):
            one = tool_frame(u, f, sign)
            many = tool_frames(u[None], f[None], sign)[0]
            assert one.shape == (3, 3) and one.dtype == np.float64
            assert one.tobytes() == many.tobytes(), (u, f, sign)


def test_tool_frame_rows_orthonormal_and_mirrored():
    u, f = np.array([0.0, 0.6, 0.8]), np.array([1.0, 2.0, 0.5])
    F = tool_frame(u, f)
    assert np.allclose(F @ F.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(F) > 0
    Fm = tool_frame(u, f, -1)
    assert np.linalg.det(Fm) < 0
    assert np.array_equal(Fm[0], -F[0]) and np.array_equal(Fm[1:], F[1:])
