"""A hostile OPC UA client, run as a separate process: many logins at once.

    python opcua_flood.py --url URL --logins N [--concurrency C] [--user U --password P]

Opens ``N`` sessions on the None policy, ``C`` at a time, each logging in with the given
user and password (a wrong password by default), and prints one JSON object:
``{"attempts", "accepted", "refused", "elapsed_s"}``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import time


async def login(url: str, user: str, password: str) -> bool:
    from asyncua import Client

    client = Client(url, timeout=5)
    client.set_user(user)
    client.set_password(password)
    try:
        await client.connect()
    except Exception:  # a refused login is what we count
        return False
    await client.disconnect()
    return True


async def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--logins", type=int, default=100)
    ap.add_argument("--concurrency", type=int, default=20)
    ap.add_argument("--user", default="line3")
    ap.add_argument("--password", default="wrong")
    args = ap.parse_args()
    logging.disable(logging.CRITICAL)
    gate = asyncio.Semaphore(args.concurrency)

    async def one() -> bool:
        async with gate:
            return await login(args.url, args.user, args.password)

    t0 = time.monotonic()
    results = await asyncio.gather(*(one() for _ in range(args.logins)))
    print(
        json.dumps(
            {
                "attempts": len(results),
                "accepted": sum(results),
                "refused": len(results) - sum(results),
                "elapsed_s": round(time.monotonic() - t0, 2),
            }
        )
    )


if __name__ == "__main__":
    asyncio.run(main())
