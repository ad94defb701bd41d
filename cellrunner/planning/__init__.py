"""Motion core: pure computation, no I/O.

- ``kinematics``: :class:`ArmKinematics` (FK, Jacobian, singularity distances, analytic IK)
- ``collision``: :class:`CollisionModel` (coal; conservative motion checks)
  with ``coal_shapes`` (shapes as coal geometry), ``motion_bounds`` (the bounds maths of
  its motion checks) and ``stl`` (reading meshes)
- ``joint_path``: :func:`plan_joint_path` (direct move or OMPL RRTConnect + shortcutting)
- ``cartesian``: :func:`plan_linear` (straight TCP lines on one IK branch)
- ``timing``: :class:`MotionLimits`, :func:`time_path` (TOPP-RA, controller-rate samples)
- ``verify``: :func:`verify_trajectory` (the final independent check; seals trajectories)
- ``job_plan``: :func:`plan_job` -> :class:`JobPlan` (what ``check``, ``run``, ``dry-run``
  and ``serve`` share: a job's steps and on_error steps expanded once, its plan, its
  failures as data)
- ``task_plan``: :func:`plan_task`, :class:`TaskPlan` (plans, blends, times and verifies
  a task's steps), with ``step_planner`` (:class:`StepPlanner`: each step's motion or
  action), ``step_contacts`` (what a step may touch), ``move_plans`` (a joint move's
  sampled, proven and margin plans), ``group_timing`` (motions timed as one and verified
  piece by piece), ``corner_blend`` (their corners rounded), ``step_plan`` (the rows),
  ``force_plan`` (the force steps' lines and contacts),
  ``blockers`` (what a failure names as in the way) and ``on_error`` (on_error verified
  from every state a job can fail in)
- ``world``: :class:`CellWorld` (a cell's kinematics, collision model, limits and plans)
- ``plan_store``: :class:`PlanStore` (approved plans reused while nothing they depend on
  changed), with ``plan_files`` (a plan as a file)

Nothing is imported here so that importing the package stays cheap; OMPL and toppra are
imported inside the functions that use them.
"""
