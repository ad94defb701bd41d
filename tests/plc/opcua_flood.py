"""A hostile OPC UA client, run as a separate process: many logins at once.

    python opcua_flood.py --url URL --logins N [--concurrency C] [--user U --password P]
                          [--policy Basic256Sha256_SignAndEncrypt --cert C --key K]

Opens ``N`` sessions, ``C`` at a time (on the None policy, or on ``--policy`` with a
client certificate), each logging in with the given user and password (a wrong password
by default), and prints one JSON object:
``{"attempts", "accepted", "refused", "elapsed_s", "statuses": {name: count}}``, where
``statuses`` counts why logins were refused (``BadUserAccessDenied``,
``BadTooManyOperations``, a timeout...).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import time
from collections import Counter


async def login(args: argparse.Namespace) -> str:
    """ "ok", or the name of the status (or exception) that refused the login."""
    from asyncua import Client, ua
    from asyncua.crypto import security_policies as sp

    client = Client(args.url, timeout=5)
    client.set_user(args.user)
    client.set_password(args.password)
    try:
        if args.policy != "none":
            name, mode = args.policy.split("_")
            await client.set_security(
                getattr(sp, f"SecurityPolicy{name}"),
                args.cert,
                args.key,
                mode=getattr(ua.MessageSecurityMode, mode),
            )
        await client.connect()
    except ua.UaStatusCodeError as exc:  # a refused login is what we count
        return type(exc).__name__
    except Exception as exc:
        return type(exc).__name__
    await client.disconnect()
    return "ok"


async def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--logins", type=int, default=100)
    ap.add_argument("--concurrency", type=int, default=20)
    ap.add_argument("--user", default="line3")
    ap.add_argument("--password", default="wrong")
    ap.add_argument("--policy", default="none")
    ap.add_argument("--cert")
    ap.add_argument("--key")
    args = ap.parse_args()
    logging.disable(logging.CRITICAL)
    gate = asyncio.Semaphore(args.concurrency)

    async def one() -> str:
        async with gate:
            return await login(args)

    t0 = time.monotonic()
    results = await asyncio.gather(*(one() for _ in range(args.logins)))
    accepted = results.count("ok")
    print(
        json.dumps(
            {
                "attempts": len(results),
                "accepted": accepted,
                "refused": len(results) - accepted,
                "elapsed_s": round(time.monotonic() - t0, 2),
                "statuses": dict(Counter(r for r in results if r != "ok")),
            }
        )
    )


if __name__ == "__main__":
    asyncio.run(main())
