"""The virtual UR controller: Dashboard, RTDE and script servers backed by a physics.

Start one with :func:`cellrunner.twin.server.run_twin` (blocking) or, in-process,
``TwinServer(make_controller("ur5e"), host="127.0.0.2").start()``; from a shell:
``python -m cellrunner.twin ur5e --host 127.0.0.2``. Modules:

- ``controller``: modes, safety, IO, registers, the period tick;
- ``physics``: the Physics Protocol the controller steps, and a kinematic physics;
- ``motion``: movej/movel/servoj/speedj/stop profiles; ``kinematics``: FK/IK;
- ``script``: ur_rtde's control-script register protocol and simple programs;
- ``rtde``, ``dashboard``: the two protocols; ``server``: sockets, loop, fault channel.
"""
