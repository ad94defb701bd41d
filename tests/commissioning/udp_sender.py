"""A program that streams twists to `cellrunner jog --input udp:PORT`, written with the
standard library only (no cellrunner import), run in its own process.

    python udp_sender.py HOST PORT --rate 100 --phase 0,0,0.05:1.0 [--phase ...]

Each phase is ``vx,vy,vz:seconds`` (m/s, base frame). Prints one JSON line:
``{"first_s": ..., "last_s": ..., "sent": N}`` (time.monotonic, shared by every process).
"""

import argparse
import json
import socket
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("host")
    parser.add_argument("port", type=int)
    parser.add_argument("--rate", type=float, default=100.0)
    parser.add_argument("--phase", action="append", default=[])
    parser.add_argument("--frame", default="base")
    args = parser.parse_args()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    seq, first, last = 0, None, None
    for phase in args.phase:
        speeds, seconds = phase.split(":")
        twist = [float(x) for x in speeds.split(",")] + [0.0, 0.0, 0.0]
        t_end = time.monotonic() + float(seconds)
        while True:
            now = time.monotonic()
            if now >= t_end:
                break
            seq += 1
            datagram = {"seq": seq, "frame": args.frame, "twist": twist}
            sock.sendto(json.dumps(datagram).encode(), (args.host, args.port))
            first = now if first is None else first
            last = now
            time.sleep(max(0.0, 1.0 / args.rate - (time.monotonic() - now)))
    print(json.dumps({"first_s": first, "last_s": last, "sent": seq}), flush=True)


if __name__ == "__main__":
    main()
