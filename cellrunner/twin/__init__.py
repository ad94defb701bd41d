"""The virtual UR controller: Dashboard, RTDE and script servers backed by a physics.

Start one with :func:`cellrunner.twin.server.run_twin` (blocking, until its stop event)
or ``python -m cellrunner.twin ur5e --host 127.0.0.2``; drive faults with
:class:`cellrunner.twin.server.FaultClient` (TCP 29990 on the same host).

Run it in its **own process**: ur_rtde's client constructors hold the Python GIL while
they wait for the controller's first answer, so a ur_rtde client in the same process as
the twin's threads deadlocks.

Modules:

- ``controller``: modes, safety, IO, registers, the period tick;
- ``physics``: the Physics Protocol the controller steps, and a kinematic physics;
- ``motion``: movej/movel/servoj/speedj/stop profiles; ``kinematics``: FK/IK;
- ``script``: ur_rtde's control-script register protocol and simple programs;
- ``rtde``, ``dashboard``: the two protocols; ``server``: sockets, loop, fault channel.
"""
