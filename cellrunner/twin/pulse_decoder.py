"""The virtual controller's pulse decoders: conveyor encoders counted as UR's are.

A UR controller decodes up to two incremental encoders wired to its digital inputs
(URScript ``encoder_enable_pulse_decode(encoder_index, decoder_type, A, B)``) and keeps
each one's tick count (``encoder_get_tick_count(encoder_index)``). Here the pulses come
from the twin's physics: a belt whose encoder the cell wires to decoder ``index``
(``encoder: {source: ur, index, ticks_per_m}``) gives ``travel x ticks_per_m`` whole
ticks (:meth:`EncoderSource.encoder_ticks`).

- ``decoder_type`` 0 disables the decoder (its count stays), 1 is a quadrature encoder
  (A and B 90 deg apart: the count follows the belt both ways), 2, 3 and 4 count edges of
  A alone (both, rising, falling: the count only grows, whichever way the belt runs);
- ``A``/``B``: 0-3 standard digital inputs DI0-3, 8-11 configurable inputs CI0-3 (B is
  only read by a quadrature decoder);
- the count is a signed 32-bit integer that wraps (``encoder_set_tick_count`` sets it).

The controller does not stream the count over RTDE by itself: a thread of the program
relays it into an output int register each period. The twin plays that relay: an enabled
decoder ``index`` writes its count into ``output_int_register_{TICK_REGISTER + index}``
every period, where an RTDE client (the UR backend) subscribes it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from cellrunner.model.conveyor import UR_TICK_REGISTER

__all__ = ["DECODER_INPUTS", "TICK_REGISTER", "EncoderSource", "PulseDecoders", "wrap_int32"]

#: output int register of decoder 0's count (decoder 1's is the next one)
TICK_REGISTER = UR_TICK_REGISTER
#: the inputs a decoder may take its pulses on: DI0-3 (0-3) and CI0-3 (8-11)
DECODER_INPUTS = frozenset({0, 1, 2, 3, 8, 9, 10, 11})
DECODER_TYPES = frozenset({0, 1, 2, 3, 4})
ENCODER_INDICES = (0, 1)


def wrap_int32(count: int) -> int:
    """``count`` as the controller keeps it: a signed 32-bit integer that wraps."""
    return (count + 2**31) % 2**32 - 2**31


@runtime_checkable
class EncoderSource(Protocol):
    """A physics whose conveyors' encoders are wired to the pulse decoders."""

    def encoder_ticks(self, index: int) -> int | None:
        """The whole ticks given so far by the encoder on decoder ``index``; None when none
        is wired there (or the world is not built yet)."""


@dataclass
class _Decoder:
    decoder_type: int
    count: int = 0
    last_raw: int | None = None


class PulseDecoders:
    """The two pulse decoders of one controller: configured by the program, updated
    every period (:meth:`update`)."""

    def __init__(self) -> None:
        self._decoders: dict[int, _Decoder] = {}

    def enable(self, index: int, decoder_type: int, a: int, b: int) -> None:
        """``encoder_enable_pulse_decode``; raises ValueError naming the valid choices (the
        program fails as a controller's does)."""
        if index not in ENCODER_INDICES:
            raise ValueError(f"encoder_index {index} is not 0 or 1")
        if decoder_type not in DECODER_TYPES:
            raise ValueError(f"decoder_type {decoder_type} is not one of 0, 1, 2, 3, 4")
        for name, pin in (("A", a), ("B", b)):
            if pin not in DECODER_INPUTS:
                raise ValueError(
                    f"encoder input {name}={pin} is not one of 0-3 (DI0-3) or 8-11 (CI0-3)"
                )
        old = self._decoders.get(index)
        self._decoders[index] = _Decoder(decoder_type, old.count if old is not None else 0)

    def set_tick_count(self, index: int, count: int) -> None:
        """``encoder_set_tick_count``: the count of decoder ``index`` becomes ``count``."""
        decoder = self._decoders.get(index)
        if decoder is None:
            raise ValueError(f"encoder {index} is not enabled (encoder_enable_pulse_decode)")
        decoder.count = wrap_int32(int(count))

    def tick_count(self, index: int) -> int | None:
        """``encoder_get_tick_count``: the count of decoder ``index``; None when it was
        never enabled."""
        decoder = self._decoders.get(index)
        return None if decoder is None else decoder.count

    def update(self, physics: object, output_int: list[int]) -> None:
        """One controller period: count the pulses of ``physics`` since the last one and
        relay each enabled decoder's count into ``output_int`` (the output int
        registers)."""
        source = physics
        if not self._decoders or not isinstance(source, EncoderSource):
            return
        for index, decoder in self._decoders.items():
            raw = source.encoder_ticks(index)
            if raw is None:
                continue
            delta = 0 if decoder.last_raw is None else raw - decoder.last_raw
            decoder.last_raw = raw
            if decoder.decoder_type == 1:
                decoder.count = wrap_int32(decoder.count + delta)
            elif decoder.decoder_type in (2, 3, 4):
                decoder.count = wrap_int32(decoder.count + abs(delta))
            output_int[TICK_REGISTER + index] = decoder.count
