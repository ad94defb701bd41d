"""Robot backends: ``sim`` (MuJoCo twin) and ``ur`` (ur_rtde), behind one Protocol."""
