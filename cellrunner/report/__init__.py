"""Reports a person opens after ``dry-run --report DIR``.

::

    recorder.RunRecorder   samples of the run (joints, TCP, wrist force, IO) and step marks
    views                  renders that see the work: a top and a 3/4 view, walls in the
                           way drawn transparent, the TCP path and steps labelled
    plots                  TCP path with the fixtures (top and side), joints, force and IO
                           timelines (matplotlib, Agg)
    slots                  the per-slot planned cycle table (check's plans, from the cache)
    page                   index.html that puts them together
    write.write_report     writes the folder; the only call ``dry-run`` makes

Nothing here drives the robot: it reads what the run recorded and the cell's geometry.
"""

from cellrunner.report.recorder import RunRecorder
from cellrunner.report.write import write_report

__all__ = ["RunRecorder", "write_report"]
