"""An encoder's 32-bit tick count as it wraps, unwrapped (SPEC section 13): the UR pulse
decoder's count (a signed int32 in an RTDE register) and the PLC's (a uint32 in two
holding registers) are the same count modulo 2**32, so one unwrapping serves both."""

from __future__ import annotations

from dataclasses import dataclass

#: the count wraps modulo this
COUNT_MODULUS = 2**32


@dataclass
class WrappingCount:
    """One encoder's count, unwrapped: the last raw reading and the ticks so far. A step
    between two readings is taken as the shorter way round (less than 2**31 ticks either
    way), so the travel runs on through a wrap, whether the raw count is signed or not."""

    raw: int | None = None
    ticks: int = 0

    def note(self, raw: int) -> int:
        """The ticks so far, with the reading ``raw`` (signed or unsigned 32-bit)."""
        if self.raw is not None:
            half = COUNT_MODULUS // 2
            self.ticks += (raw - self.raw + half) % COUNT_MODULUS - half
        self.raw = raw
        return self.ticks
