"""The RTDE protocol of one connection, without sockets: framing and recipes."""

from __future__ import annotations

import struct

from cellrunner.twin.rtde import InputOwners, RtdeSession
from cellrunner.twin.server import make_controller


def msg(kind: str, payload: bytes = b"") -> bytes:
    return struct.pack(">HB", 3 + len(payload), ord(kind)) + payload


def session(owners: InputOwners | None = None, sid: int = 1) -> RtdeSession:
    return RtdeSession(sid, make_controller("ur5e"), owners or InputOwners())


def test_feed_handles_byte_by_byte_and_coalesced_input():
    s = session()
    stream = (
        msg("V", struct.pack(">H", 2))
        + msg("v")
        + msg("I", b"input_int_register_0,input_double_register_0")
    )
    replies = []
    for i in range(len(stream)):
        replies += s.feed(stream[i : i + 1])
    assert [r[2] for r in replies] == [ord("V"), ord("v"), ord("I")]
    assert replies[2][3:] == b"\x01INT32,DOUBLE"
    coalesced = s.feed(msg("U", b"\x01" + struct.pack(">id", 7, 2.5)) * 2 + msg("S")[:2])
    assert coalesced == []
    assert s.ctl.reg.input_int[0] == 7 and s.ctl.reg.input_double[0] == 2.5
    assert s.feed(msg("S")[2:]) == [msg("S", b"\x01")]


def test_inputs_used_by_another_connection_are_in_use():
    owners = InputOwners()
    a, b = session(owners, 1), session(owners, 2)
    a.feed(msg("V", struct.pack(">H", 2)))
    b.feed(msg("V", struct.pack(">H", 2)))
    assert a.feed(msg("I", b"input_int_register_5"))[0][3:] == b"\x01INT32"
    assert (
        b.feed(msg("I", b"input_int_register_5,input_int_register_6"))[0][3:] == b"\x00IN_USE,INT32"
    )
    a.close()
    assert b.feed(msg("I", b"input_int_register_5"))[0][3:] == b"\x01INT32"


def test_output_recipe_decimates_to_requested_frequency():
    s = session()
    s.feed(msg("V", struct.pack(">H", 2)))
    reply = s.feed(msg("O", struct.pack(">d", 125.0) + b"timestamp,actual_q,robot_mode"))[0]
    assert reply[3:] == b"\x01DOUBLE,VECTOR6D,INT32"
    s.feed(msg("S"))
    s.ctl.tick()
    first = s.output_packets()  # the first package goes out at once
    assert len(first) == 1
    assert struct.unpack(">H", first[0][:2])[0] == 3 + 1 + 8 + 48 + 4
    counts = []
    for _ in range(40):
        s.ctl.tick()
        counts.append(len(s.output_packets()))
    assert sum(counts) == 10  # 125 of 500 Hz
    assert counts[2::4] == [1] * 10
