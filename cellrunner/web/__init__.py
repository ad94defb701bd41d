"""The operators' view of a serving cell (``serve --http``): a read-only status page
that updates live and Prometheus metrics.

* :mod:`~cellrunner.web.board` - :class:`StatusBoard` builds a JSON-ready snapshot from
  the cell's public ``status()`` (a :class:`~cellrunner.model.cellport.CellPort`), its
  own read connection to the journal and the PLC links; it never touches the robot.
* :mod:`~cellrunner.web.alarms` - the active alarms and what to do about each.
* :mod:`~cellrunner.web.metrics` - the Prometheus text exposition format.
* :mod:`~cellrunner.web.server` - a stdlib HTTP server on its own thread: ``/`` (the
  page), ``/status.json``, ``/metrics``, the live 3D view's ``/live/...`` and three.js.
* :mod:`~cellrunner.web.live_feed` - :class:`LiveFeed`, the control loop's observer that
  samples the measured arm 20 times a second without waiting on anything.
* :mod:`~cellrunner.web.live_scene` - the 3D scene from the cell model, link poses by the
  arm's kinematics, a job's planned path and the part held at each step.
* :mod:`~cellrunner.web.live` - :class:`LiveView`, the cached JSON the page draws from.
"""
