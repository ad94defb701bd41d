"""The MuJoCo twin and the ``sim`` backend.

Importing this package does not import MuJoCo; :mod:`.mjcf`, :mod:`.world`,
:mod:`.backend` and :mod:`.render` load it lazily when a model is built or rendered.

- :mod:`.description` -- :class:`TwinDescription` and friends, what the twin is built from
- :mod:`.mjcf` -- the MJCF model of a description
- :mod:`.world` -- :class:`SimWorld`, the physics stepped one controller period at a time
- :mod:`.backend` -- :class:`SimBackend`, the RobotBackend Protocol over the world
- :mod:`.render` -- offscreen PNGs and matplotlib plots for dry-run reports
- :mod:`.demo` -- a demo cell and demo motions for tests and benchmarks
"""
