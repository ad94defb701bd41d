"""The torques a motion asks of the arm's joints, for timing (:mod:`.timing`).

The arm's links carry the twin's masses and inertias
(:mod:`cellrunner.model.arm_dynamics`), each joint its drive's reflected inertia; the tool
is its payload mass at its centre of gravity, and the heaviest part the cell's grips may
carry sits as a point mass at the TCP (every motion is timed as if carrying it: a part is
light beside the arm, and one timing serves the moves with and without it). Gravity is
left out: the controller (and the twin) compensate the arm's and the tool's weight
whatever the motion, so a motion's torques are its inertial ones, ``M(q) q'' + C(q, q')
q'`` (pinocchio's recursive Newton-Euler).

Along a path ``q(s)`` timed by ``s(t)``: ``q' = q_s s'`` and ``q'' = q_s s'' + q_ss s'^2``,
so the torques are ``a(s) s'' + b(s) s'^2`` with ``a = M q_s`` and ``b = M q_ss + C(q, q_s)
q_s``: linear in TOPP-RA's variables, as its torque constraint wants.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from cellrunner.model.arm_dynamics import armature_kgm2, joint_torque_max_nm, link_inertias
from cellrunner.model.robots import JOINT_NAMES, RobotSpec
from cellrunner.planning.kinematics import dh_link

#: the share of a joint's rated torque a plan may ask for: the rest is for what the model
#: leaves out (a carried part's weight, the servo's own lag, the joints' friction)
TORQUE_SHARE = 0.9


class ArmDynamics:
    """The inverse dynamics (no gravity) of one arm with its tool and heaviest part."""

    def __init__(
        self,
        spec: RobotSpec,
        T_flange_tcp: np.ndarray,
        payload_kg: float,
        payload_cog_m: tuple[float, float, float],
        part_kg: float,
    ) -> None:
        links = link_inertias(spec)
        if links is None:
            raise ValueError(f"no link inertias for robot model {spec.name!r}")
        self.torque_max_nm = np.asarray(joint_torque_max_nm(spec), float)
        model = pin.Model()
        model.name = spec.name
        model.gravity = pin.Motion.Zero()
        parent, placement = 0, pin.SE3.Identity()
        for i, name in enumerate(JOINT_NAMES):
            parent = model.addJoint(parent, pin.JointModelRZ(), placement, name)
            link = links[i]
            xx, yy, zz, xy, xz, yz = link.inertia_kgm2
            inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            model.appendBodyToJoint(
                parent,
                pin.Inertia(link.mass_kg, np.asarray(link.com_m), inertia),
                pin.SE3.Identity(),
            )
            placement = dh_link(spec.d_m[i], spec.a_m[i], spec.alpha_rad[i])
        # the tool and the part, both on the last joint (the flange is fixed to it)
        T_flange = placement.homogeneous
        p_cog = T_flange @ np.array([*payload_cog_m, 1.0])
        p_tcp = (T_flange @ np.asarray(T_flange_tcp, float))[:, 3]
        for mass, p in ((payload_kg, p_cog), (part_kg, p_tcp)):
            if mass > 0:
                model.appendBodyToJoint(
                    parent, pin.Inertia(mass, p[:3], np.zeros((3, 3))), pin.SE3.Identity()
                )
        model.armature = np.asarray(armature_kgm2(spec), float)
        self.model = model
        self.data = model.createData()

    def torques_nm(
        self, q_rad: np.ndarray, qd_rad_s: np.ndarray, qdd_rad_s2: np.ndarray
    ) -> np.ndarray:
        """The joint torques (N x 6, N m) of the states in the rows (N x 6 each)."""
        q, v, a = (np.atleast_2d(np.asarray(x, float)) for x in (q_rad, qd_rad_s, qdd_rad_s2))
        out = np.empty_like(q)
        for k in range(len(q)):
            out[k] = pin.rnea(self.model, self.data, q[k], v[k], a[k])
        return out

    def path_terms(
        self, q_rad: np.ndarray, dq_ds: np.ndarray, d2q_ds2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``a(s)``, ``b(s)`` (N x 6) of the module docstring at the path's points."""
        zero = np.zeros_like(np.atleast_2d(dq_ds))
        a = self.torques_nm(q_rad, zero, dq_ds)
        b = self.torques_nm(q_rad, dq_ds, d2q_ds2)
        return a, b
