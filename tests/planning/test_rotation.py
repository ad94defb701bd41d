"""Quaternion helpers of the straight-line planner against scipy's rotations."""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from cellrunner.planning.cartesian import quaternion, rotation_matrix, slerp


def test_quaternion_round_trip_and_slerp_match_scipy():
    rng = np.random.default_rng(3)
    rotations = Rotation.random(200, random_state=rng)
    # include the awkward ones: identity, half turns about each axis
    extra = Rotation.from_rotvec(
        [[0, 0, 0], [np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], [0, 0, 1e-9]]
    )
    matrices = np.concatenate([rotations.as_matrix(), extra.as_matrix()])
    for R in matrices:
        assert np.allclose(rotation_matrix(quaternion(R)), R, atol=1e-12)
    for R0, R1 in itertools.pairwise(matrices):
        ours = [
            rotation_matrix(slerp(quaternion(R0), quaternion(R1), u)) for u in (0.0, 0.3, 0.5, 1.0)
        ]
        theirs = Slerp([0, 1], Rotation.from_matrix([R0, R1]))([0.0, 0.3, 0.5, 1.0]).as_matrix()
        assert np.allclose(ours, theirs, atol=1e-9)
