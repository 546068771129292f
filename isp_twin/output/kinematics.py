"""Kinematics of the drawn turntable and gimbals: joint rotations and the line of sight.

Plain numpy (no rerun): the seven joints nested outermost first, the rotation
of each as a quaternion for the 3D view, and the camera boresight carried
through all of them into the world frame.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from isp_twin.vocabulary import JOINT_CHAIN

__all__ = ["BORESIGHT", "JOINTS", "joint_quaternions", "line_of_sight"]

#: The seven joints of `JOINT_CHAIN` (outermost first, each nested in the
#: previous one), each with its rotation axis in the parent frame (the MJCF model's).
JOINTS: tuple[tuple[str, str], ...] = tuple(zip(JOINT_CHAIN, ("z", "y", "x", "z", "y", "y", "z")))
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}
#: Camera boresight in the inner_az frame (+x).
BORESIGHT = np.array([1.0, 0.0, 0.0])


def joint_quaternions(angle: np.ndarray, axis: str) -> np.ndarray:
    """Rotations by `angle` about a frame axis, as quaternions.

    Args:
        angle: joint angles [rad], shape (N,).
        axis: ``"x"``, ``"y"`` or ``"z"``.

    Returns:
        Quaternions in Rerun's (x, y, z, w) order, shape (N, 4).
    """
    angle = np.asarray(angle, dtype=float)
    q = np.zeros(angle.shape + (4,))
    q[..., _AXIS_INDEX[axis]] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q


def _rotation_matrices(angle: np.ndarray, axis: str) -> np.ndarray:
    """Rotation matrices about a frame axis, shape (N, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    i = _AXIS_INDEX[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.zeros(np.shape(angle) + (3, 3))
    r[..., i, i] = 1.0
    r[..., j, j] = c
    r[..., k, k] = c
    r[..., k, j] = s
    r[..., j, k] = -s
    return r


def line_of_sight(joint_angles: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    """The camera boresight (inner_az frame +x) in the world frame.

    Args:
        joint_angles: joint name -> angle [rad], shape (n,); missing joints are 0.
        n: number of samples.

    Returns:
        Unit vectors, shape (n, 3).
    """
    rot = np.broadcast_to(np.eye(3), (n, 3, 3))
    for name, axis in JOINTS:
        if name in joint_angles:
            rot = rot @ _rotation_matrices(np.asarray(joint_angles[name], dtype=float), axis)
    return rot @ BORESIGHT
