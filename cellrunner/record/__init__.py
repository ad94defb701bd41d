"""Recordings of a job (``--record FILE.rrd|FILE.mcap``, SPEC section 13): the 3D scene over
time (arm, tool, fixtures and parts as meshes with their poses), the planned and measured
TCP paths, the step timeline, IO, wrist force and vacuum as plots, depth images and the
obstacle map, written for Rerun (``.rrd``) or Foxglove (``.mcap``).

    sink.Sink            what a recording file is written through (one Protocol)
    scene.SceneModel     the cell's bodies as meshes and their poses from a joint state
    collector.Collector  the control-loop observer: snapshots into a queue, written by a
                         worker thread (never on the loop's thread)
    rrd.RerunSink        a Sink writing Rerun's .rrd (``cellrunner[record]``)
    mcap_file.McapSink   a Sink writing MCAP with Foxglove's schemas (``cellrunner[record]``)
    files                a sink by file suffix; ``serve``'s folder of one file per job
"""
