"""Motion core: pure computation, no I/O.

- ``kinematics``: :class:`ArmKinematics` (FK, Jacobian, singularity distances, analytic IK)
- ``collision``: :class:`CollisionModel` (coal; conservative motion checks)
  with ``coal_shapes`` (shapes as coal geometry), ``motion_bounds`` (the bounds maths of
  its motion checks) and ``stl`` (reading meshes)
- ``joint_path``: :func:`plan_joint_path` (direct move or OMPL RRTConnect + shortcutting)
- ``cartesian``: :func:`plan_linear` (straight TCP lines on one IK branch)
- ``timing``: :class:`MotionLimits`, :func:`time_path` (TOPP-RA, controller-rate samples)
- ``verify``: :func:`verify_trajectory` (the final independent check; seals trajectories)
- ``task_plan``: :func:`plan_task`, :class:`TaskPlan` (what ``check`` and the engine use:
  plans, blends, times and verifies a task's steps), with ``force_plan`` (the force
  steps' lines and contacts) and ``blockers`` (what a failure names as in the way)
- ``world``: :class:`CellWorld` (a cell's kinematics, collision model and limits)
- ``cache``: :func:`plan_cached` (approved plans reused while nothing they depend on changed)

Nothing is imported here so that importing the package stays cheap; OMPL and toppra are
imported inside the functions that use them.
"""
