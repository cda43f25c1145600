"""Rigid transforms as (position, quaternion xyzw) pairs; seeds that make checks repeatable."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence

import numpy as np
import pybullet as p

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Pose = tuple[Vec3, Quat]


def yaw_quat(yaw: float) -> Quat:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def yaw_of(q: Quat) -> float:
    """The heading of a frame's x axis about the world's z (of an upright body, its yaw)."""
    axes = rotation(q)
    return math.atan2(float(axes[1, 0]), float(axes[0, 0]))


def compose(a: Pose, b: Pose) -> Pose:
    pos, orn = p.multiplyTransforms(a[0], a[1], b[0], b[1])
    return tuple(pos), tuple(orn)


def invert(a: Pose) -> Pose:
    pos, orn = p.invertTransform(a[0], a[1])
    return tuple(pos), tuple(orn)


def rotation(q: Quat) -> np.ndarray:
    """3x3 rotation matrix of a quaternion; columns are the frame's axes in world."""
    return np.asarray(p.getMatrixFromQuaternion(q)).reshape(3, 3)


def quat_from_axes(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> Quat:
    """Quaternion of the frame whose axes (orthonormal, right-handed) are x, y, z."""
    m = np.column_stack([x, y, z])
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s)
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)  # type: ignore[return-value]


def angle_between(a: Quat, b: Quat) -> float:
    """The rotation angle (radians) that takes orientation a to b."""
    dot = abs(sum(x * y for x, y in zip(a, b, strict=True)))
    return 2.0 * math.acos(min(1.0, dot))


def derived_seed(seed: int, *parts: object) -> int:
    """A seed in [1, 2^31 - 1) that depends only on the run's seed and the check's inputs, so a
    check gives the same verdict whatever the search did before it."""
    text = repr((seed, *(_rounded(x) for x in parts))).encode()
    return 1 + int.from_bytes(hashlib.blake2b(text, digest_size=8).digest(), "big") % (2**31 - 2)


def _rounded(x: object) -> object:
    if isinstance(x, float):
        return round(x, 9)
    if isinstance(x, Sequence) and not isinstance(x, str):
        return tuple(_rounded(v) for v in x)
    return x
