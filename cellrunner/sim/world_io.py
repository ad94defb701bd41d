"""The twin controller's IO image: the outputs a program sets and the inputs the twin's
sensors drive (presence sensors, the jaws' and cups' inputs, the tool changer's lock,
the cell's input rules) or a test or scripted peer sets. Part of :class:`.world.SimWorld`
(its ``io``); the world's ``outputs`` and ``inputs`` are these dicts."""

from __future__ import annotations

from typing import Any

from cellrunner.errors import BackendError
from cellrunner.sim.input_rules import InputRules


class IoImage:
    """The IO image of one built SimWorld (constructed when it builds)."""

    def __init__(self, world: Any) -> None:
        self.world = world
        d = world.description
        self.outputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_outputs}
        self.inputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_inputs}
        self._scripted_inputs: dict[str, float | bool] = {}
        self.rules = InputRules(d.input_rules) if d.input_rules else None

    def set_output(self, channel: str, value: bool | float) -> None:
        if channel not in self.outputs:
            raise BackendError(f"unknown output {channel!r}; known: {', '.join(self.outputs)}")
        self.outputs[channel] = value

    def set_input(self, channel: str, value: bool | float) -> None:
        """Drive an input that no twin sensor drives (a test or a scripted peer)."""
        if channel not in self.inputs:
            raise BackendError(f"unknown input {channel!r}; known: {', '.join(self.inputs)}")
        if channel in self._sensor_channels():
            raise BackendError(f"input {channel!r} is driven by a twin sensor")
        self._scripted_inputs[channel] = value
        self.inputs[channel] = value

    def _sensor_channels(self) -> set[str]:
        w = self.world
        chans = {s.channel for s in w.description.presence_sensors}
        if w.description.vacuum is not None and w.description.vacuum.vacuum_ok_input:
            chans.add(w.description.vacuum.vacuum_ok_input)
        if w.description.tool_changer is not None and w.description.tool_changer.locked_input:
            chans.add(w.description.tool_changer.locked_input)
        if self.rules is not None:
            chans |= self.rules.channels()
        if w.jaws is not None:
            chans |= w.jaws.channels()
        return chans

    def update_inputs(self) -> None:
        """The sensor-driven inputs from this period's physics."""
        w = self.world
        if w.jaws is not None:
            w.jaws.update_inputs(self.inputs)
        if w.vacuum is not None and w.vacuum.vac.vacuum_ok_input:
            self.inputs[w.vacuum.vac.vacuum_ok_input] = w.vacuum.vacuum_ok
        if w.changer is not None and w.changer.desc.locked_input:
            self.inputs[w.changer.desc.locked_input] = w.changer.locked
        for sensor in w.description.presence_sensors:
            self.inputs[sensor.channel] = any(
                bool(sensor.sees(w.data.xpos[b])) for b in w.ids.part_bodies.values()
            )
        if self.rules is not None:
            xpos = w.data.xpos
            self.inputs.update(
                self.rules.evaluate(
                    w.time_s,
                    self.outputs,
                    (xpos[b].tolist() for b in w.ids.part_bodies.values()),
                )
            )


def _zero(channel: str) -> float | bool:
    return 0.0 if channel[:2] in ("AI", "AO") else False
