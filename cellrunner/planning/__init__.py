"""Motion core: pure computation, no I/O.

- ``kinematics``: :class:`ArmKinematics` (FK, Jacobian, singularity distances, analytic IK)
- ``collision``: :class:`CollisionModel` (coal; conservative motion checks)
- ``joint_path``: :func:`plan_joint_path` (direct move or OMPL RRTConnect + shortcutting)
- ``cartesian``: :func:`plan_linear` (straight TCP lines on one IK branch)
- ``timing``: :class:`MotionLimits`, :func:`time_path` (TOPP-RA, controller-rate samples)
- ``verify``: :func:`verify_trajectory` (the final independent check; seals trajectories)
- ``planner``: :class:`MotionPlanner`, :class:`Segment` (the façade ``check`` uses)

Nothing is imported here so that importing the package stays cheap; OMPL and toppra are
imported inside the functions that use them.
"""
