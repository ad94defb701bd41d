"""Commissioning on the arm: poses read from the controller (``teach``, ``calibrate-tcp``)
and written back into the cell file by one writer (:mod:`.cellfile`) that changes nothing
but the pose it writes."""
