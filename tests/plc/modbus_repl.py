"""A PLC stand-in, run as a separate process: one Modbus client driven by JSON lines.

    python modbus_repl.py --lib pymodbus|pyModbusTCP --host H --port P

Each stdin line is a JSON request, each stdout line the JSON answer:

    {"op": "read", "addr": 100, "count": 14}     -> {"ok": true, "values": [...]}
    {"op": "write", "addr": 1, "values": [1]}    -> {"ok": true} | {"ok": false, "exception": 2}
    {"op": "heartbeat", "on": true}              -> PLC heartbeat (reg 0) every 100 ms
    {"op": "wait", "addr": 101, "mask": 8, "value": 8, "timeout": 5}
                                                 -> {"ok": bool, "values": [reg], "elapsed": s}
    {"op": "quit"}

The two client libraries are independent implementations of the protocol (pymodbus's
sync client, and pyModbusTCP); the PLC heartbeat thread shares the client under a lock.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time


class PymodbusClient:
    def __init__(self, host: str, port: int) -> None:
        from pymodbus.client import ModbusTcpClient

        self.client = ModbusTcpClient(host, port=port, timeout=2, retries=0)
        if not self.client.connect():
            raise SystemExit(f"cannot connect to {host}:{port}")

    def read(self, addr: int, count: int) -> tuple[list[int] | None, int]:
        rr = self.client.read_holding_registers(addr, count=count)
        if rr.isError():
            return None, int(getattr(rr, "exception_code", -1))
        return list(rr.registers), 0

    def write(self, addr: int, values: list[int]) -> int:
        if len(values) == 1:
            rr = self.client.write_register(addr, values[0])
        else:
            rr = self.client.write_registers(addr, values)
        return int(getattr(rr, "exception_code", -1)) if rr.isError() else 0

    def close(self) -> None:
        self.client.close()


class PyModbusTcpClient:
    def __init__(self, host: str, port: int) -> None:
        from pyModbusTCP.client import ModbusClient

        self.client = ModbusClient(host=host, port=port, auto_open=True, timeout=2.0)

    def read(self, addr: int, count: int) -> tuple[list[int] | None, int]:
        values = self.client.read_holding_registers(addr, count)
        if values is None:
            return None, int(self.client.last_except or -1)
        return list(values), 0

    def write(self, addr: int, values: list[int]) -> int:
        if len(values) == 1:
            ok = self.client.write_single_register(addr, values[0])
        else:
            ok = self.client.write_multiple_registers(addr, values)
        return 0 if ok else int(self.client.last_except or -1)

    def close(self) -> None:
        self.client.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--lib", choices=["pymodbus", "pyModbusTCP"], required=True)
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    args = ap.parse_args()
    cls = PymodbusClient if args.lib == "pymodbus" else PyModbusTcpClient
    client = cls(args.host, args.port)
    lock = threading.Lock()
    beating = threading.Event()
    done = threading.Event()

    def heartbeat() -> None:
        value = 1
        while not done.wait(0.1):
            if beating.is_set():
                with lock:
                    client.write(0, [value])
                value = value % 65535 + 1

    threading.Thread(target=heartbeat, daemon=True).start()
    print(json.dumps({"ok": True, "ready": True}), flush=True)
    for line in sys.stdin:
        req = json.loads(line)
        op = req["op"]
        if op == "quit":
            break
        if op == "read":
            with lock:
                values, exc = client.read(req["addr"], req.get("count", 1))
            reply = {"ok": exc == 0, "values": values, "exception": exc}
        elif op == "write":
            with lock:
                exc = client.write(req["addr"], req["values"])
            reply = {"ok": exc == 0, "exception": exc}
        elif op == "heartbeat":
            (beating.set if req["on"] else beating.clear)()
            reply = {"ok": True}
        elif op == "wait":
            t0 = time.monotonic()
            deadline = t0 + float(req.get("timeout", 5.0))
            values: list[int] | None = None
            ok = False
            while time.monotonic() < deadline:
                with lock:
                    values, _ = client.read(req["addr"], 1)
                if values is not None and values[0] & req["mask"] == req["value"]:
                    ok = True
                    break
                time.sleep(0.002)
            reply = {"ok": ok, "values": values, "elapsed": time.monotonic() - t0}
        else:
            reply = {"ok": False, "error": f"unknown op {op}"}
        print(json.dumps(reply), flush=True)
    done.set()
    client.close()


if __name__ == "__main__":
    main()
