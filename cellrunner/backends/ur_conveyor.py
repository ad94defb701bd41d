"""The cell's conveyor encoders read on a UR controller (SPEC section 13): the UR
backend's ``conveyor_travel_m``.

- ``{source: ur, index, ticks_per_m}``: the controller's pulse decoder. At every connect
  the backend enables decoder ``index`` (quadrature, A/B on ``DECODER_PINS``) with a
  secondary program sent to the script port (a ``sec`` program runs beside the running
  control script without stopping it); the decoder's tick count is relayed by the program
  into ``output_int_register_{TICK_REGISTER + index}``, which the backend subscribes on
  its RTDE state stream and reads every controller period. The count is a signed 32-bit
  integer that wraps: its steps are unwrapped
  (:class:`~cellrunner.model.encoder_count.WrappingCount`), so the travel runs on.
- ``{source: speed, mps}``: no encoder; the belt's travel is ``mps`` x the controller's
  time.
- ``{source: plc, register}``: the count is in the PLC's holding registers, which the
  engine's PLC server holds, not the controller: not read by this backend. ``serve``
  reads them (:mod:`cellrunner.execution.plc_encoders`); ``run`` has no PLC, so the belt
  is not measured there and a ``track`` step on it ends 103.
"""

from __future__ import annotations

import socket
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from cellrunner.model.conveyor import UR_TICK_REGISTER
from cellrunner.model.encoder_count import WrappingCount

if TYPE_CHECKING:
    from cellrunner.model.conveyor import Conveyor

__all__ = ["DECODER_PINS", "SCRIPT_PORT", "TICK_REGISTER", "UREncoders", "setup_program"]

#: output int register of decoder 0's count (decoder 1's is the next one)
TICK_REGISTER = UR_TICK_REGISTER
#: the digital inputs each decoder's quadrature channels A and B are wired to: the
#: configurable inputs CI0/CI1 (8, 9) for decoder 0 and CI2/CI3 (10, 11) for decoder 1
DECODER_PINS = {0: (8, 9), 1: (10, 11)}
#: quadrature decoding (A and B 90 deg apart: the count follows the belt both ways)
QUADRATURE = 1
#: the secondary client interface, which takes script (``sec`` programs) at any time
SCRIPT_PORT = 30002


def setup_program(indices: list[int]) -> str:
    """The secondary program that enables the pulse decoders ``indices``."""
    lines = [
        f"  encoder_enable_pulse_decode({i}, {QUADRATURE}, {DECODER_PINS[i][0]}, "
        f"{DECODER_PINS[i][1]})"
        for i in sorted(indices)
    ]
    return "sec cellrunner_encoders():\n" + "\n".join(lines) + "\nend\n"


class UREncoders:
    """The conveyors of one cell as the UR backend measures them; construct (no I/O),
    :meth:`configure` at every connect, :meth:`travel_m` every period."""

    def __init__(self, conveyors: Mapping[str, Conveyor]) -> None:
        self.conveyors = dict(conveyors)
        self._counts: dict[int, WrappingCount] = {}

    @property
    def decoder_indices(self) -> list[int]:
        """The pulse decoders the cell's conveyors are wired to."""
        return sorted(
            {c.encoder.index for c in self.conveyors.values() if c.encoder.source == "ur"}
        )

    def receive_variables(self) -> list[str]:
        """The RTDE outputs to subscribe beside the arm's state."""
        return [f"output_int_register_{TICK_REGISTER + i}" for i in self.decoder_indices]

    def configure(self, host: str, timeout_s: float) -> None:
        """Enable the pulse decoders on the controller at ``host`` (a ``sec`` program on
        the script port); raises OSError when it cannot be sent. Counting restarts from
        the next reading (a reconnect does not make the belt jump)."""
        indices = self.decoder_indices
        if not indices:
            return
        with socket.create_connection((host, SCRIPT_PORT), timeout=timeout_s) as sock:
            sock.sendall(setup_program(indices).encode())
        self.restart_counts()

    def restart_counts(self) -> None:
        """Count from the next reading on, the travel going on from where it was."""
        for i in self.decoder_indices:
            count = self._counts.get(i)
            self._counts[i] = WrappingCount(ticks=count.ticks if count is not None else 0)

    def travel_m(self, name: str, receive: Any, time_s: float) -> float | None:
        """How far conveyor ``name`` has travelled, m, by the latest state of ``receive``
        (an RTDE state reader) at controller time ``time_s``; None when this backend
        cannot measure it (no such conveyor, a PLC encoder, not connected)."""
        conveyor = self.conveyors.get(name)
        if conveyor is None:
            return None
        enc = conveyor.encoder
        if enc.source == "speed" and enc.mps is not None:
            return float(enc.mps) * time_s
        if enc.source != "ur" or enc.ticks_per_m is None or receive is None:
            return None
        count = self._counts.get(enc.index)
        if count is None:
            return None
        raw = receive.value(f"output_int_register_{TICK_REGISTER + enc.index}")
        return count.note(int(raw)) / float(enc.ticks_per_m)
