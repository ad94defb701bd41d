"""The ``sim`` backend: :class:`~.backend.SimBackend`, the RobotBackend Protocol over the
MuJoCo world of :mod:`cellrunner.sim`.

Importing this package does not import MuJoCo; the world loads it when ``connect()``
builds the model.
"""
