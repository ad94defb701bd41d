"""A Modbus TCP client of raw bytes, run as its own process: it sends byte chunks exactly
as given (each in one send, with a pause between) and prints the frames it gets back.

    python raw_modbus.py HOST PORT < {"chunks": ["hex", ...], "pause_s": 0.2, "expect": N}
    -> {"frames": [{"tid": 1, "fc": 6, "pdu": "hex"}, ...], "closed": false}

It stops after ``expect`` answers, at EOF, or 5 s after the last chunk.
"""

from __future__ import annotations

import json
import socket
import sys
import time


def main() -> None:
    host, port = sys.argv[1], int(sys.argv[2])
    spec = json.loads(sys.stdin.read())
    with socket.create_connection((host, port), timeout=5) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        for i, chunk in enumerate(spec["chunks"]):
            if i:
                time.sleep(spec.get("pause_s", 0.2))
            sock.sendall(bytes.fromhex(chunk))
        data, closed, deadline = b"", False, time.monotonic() + 5
        frames: list[dict[str, object]] = []
        while len(frames) < spec["expect"] and time.monotonic() < deadline:
            sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                more = sock.recv(65536)
            except TimeoutError:
                break
            if not more:
                closed = True
                break
            data += more
            while len(data) >= 6 and len(data) >= 6 + int.from_bytes(data[4:6], "big"):
                end = 6 + int.from_bytes(data[4:6], "big")
                frame, data = data[:end], data[end:]
                frames.append(
                    {
                        "tid": int.from_bytes(frame[:2], "big"),
                        "fc": frame[7],
                        "pdu": frame[8:].hex(),
                    }
                )
    print(json.dumps({"frames": frames, "closed": closed}))


if __name__ == "__main__":
    main()
