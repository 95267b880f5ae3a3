"""Many clients at once, each on its own keep-alive connection from one of
several loopback addresses: the fan-in a proxy in front of the daemons sees.

    python3 tests/load/fanin.py URL [--clients 500] [--addresses 10] [--seconds 10] [--scene FILE]

Each client connects from 127.0.0.(2 + its number modulo --addresses) and
posts the scene (default examples/two_disks.json) to URL/v1/contact in a loop,
one request at a time, until --seconds have passed and it has sent at least
--min-requests. Prints one JSON line: requests, answers by status, connection
errors, the latency quantiles. asyncio and raw HTTP/1.1: 500 clients cost one
Python thread. tests/python/test_scale_out.py runs it through deploy/nginx.conf;
docs/benchmarks.md ("Scale-out behind nginx") reports it."""
from __future__ import annotations

import argparse
import asyncio
import json
import pathlib
import sys
import time
import urllib.parse
from collections import Counter
from dataclasses import dataclass, field
from typing import Dict, List, Optional

REPO = pathlib.Path(__file__).resolve().parents[2]


@dataclass
class Tally:
    statuses: Counter = field(default_factory=Counter)
    connection_errors: Counter = field(default_factory=Counter)
    latencies: List[float] = field(default_factory=list)
    bodies: Dict[int, bytes] = field(default_factory=dict)  # one body per status seen, for the report

    def as_dict(self) -> dict:
        lat = sorted(self.latencies)

        def q(p: float) -> Optional[float]:
            return round(1e3 * lat[min(len(lat) - 1, int(p * len(lat)))], 3) if lat else None

        return {"requests": sum(self.statuses.values()), "statuses": {str(k): v for k, v in self.statuses.items()},
                "connection_errors": dict(self.connection_errors), "p50_ms": q(0.5), "p99_ms": q(0.99),
                "max_ms": round(1e3 * lat[-1], 3) if lat else None,
                "samples": {str(k): v[:200].decode("utf-8", "replace") for k, v in self.bodies.items() if k != 200}}


async def _read_response(reader: asyncio.StreamReader) -> tuple[int, bytes, bool]:
    """Status, body and whether the server asked to close."""
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    headers = {}
    for line in lines[1:]:
        if ":" in line:
            k, v = line.split(":", 1)
            headers[k.strip().lower()] = v.strip()
    if "content-length" in headers:
        body = await reader.readexactly(int(headers["content-length"]))
    elif headers.get("transfer-encoding", "").lower() == "chunked":
        body = b""
        while True:
            size = int((await reader.readuntil(b"\r\n")).split(b";")[0], 16)
            chunk = await reader.readexactly(size + 2)
            if size == 0:
                break
            body += chunk[:-2]
    else:
        body = await reader.read()
    return status, body, headers.get("connection", "").lower() == "close"


async def _client(k: int, host: str, port: int, path: str, request: bytes, addresses: int, until: float,
                  min_requests: int, tally: Tally, timeout: float) -> None:
    source = f"127.0.0.{2 + k % addresses}"
    writer = None
    sent = 0
    try:
        while sent < min_requests or time.monotonic() < until:
            if writer is None:
                try:
                    reader, writer = await asyncio.wait_for(
                        asyncio.open_connection(host, port, local_addr=(source, 0)), timeout)
                except (OSError, asyncio.TimeoutError) as e:
                    tally.connection_errors[type(e).__name__] += 1
                    sent += 1
                    await asyncio.sleep(0.05)
                    continue
            t0 = time.monotonic()
            try:
                writer.write(request)
                status, body, close = await asyncio.wait_for(_read_response(reader), timeout)
            except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, asyncio.TimeoutError,
                    ValueError) as e:
                tally.connection_errors[type(e).__name__] += 1
                sent += 1
                writer.close()
                writer = None
                continue
            tally.latencies.append(time.monotonic() - t0)
            tally.statuses[status] += 1
            tally.bodies.setdefault(status, body)
            sent += 1
            if close:
                writer.close()
                writer = None
    finally:
        if writer is not None:
            writer.close()


async def _run(url: str, clients: int, addresses: int, seconds: float, scene: bytes, min_requests: int,
               timeout: float) -> Tally:
    u = urllib.parse.urlsplit(url)
    host, port = u.hostname or "127.0.0.1", u.port or 80
    path = "/v1/contact"
    request = (f"POST {path} HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Type: application/json\r\n"
               f"Content-Length: {len(scene)}\r\n\r\n").encode() + scene
    tally = Tally()
    until = time.monotonic() + seconds
    await asyncio.gather(*(_client(k, host, port, path, request, addresses, until, min_requests, tally, timeout)
                           for k in range(clients)))
    return tally


def run(url: str, clients: int = 500, addresses: int = 10, seconds: float = 10.0, scene: Optional[bytes] = None,
        min_requests: int = 2, timeout: float = 120.0) -> dict:
    """The tally of a fan-in run (see the module's text)."""
    if scene is None:
        scene = (REPO / "examples" / "two_disks.json").read_bytes()
    t0 = time.monotonic()
    tally = asyncio.run(_run(url, clients, addresses, seconds, scene, min_requests, timeout))
    out = tally.as_dict()
    out.update(clients=clients, addresses=addresses, seconds=round(time.monotonic() - t0, 3))
    return out


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url")
    ap.add_argument("--clients", type=int, default=500)
    ap.add_argument("--addresses", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--min-requests", type=int, default=2)
    ap.add_argument("--scene", type=pathlib.Path)
    args = ap.parse_args(argv)
    print(json.dumps(run(args.url, args.clients, args.addresses, args.seconds,
                         args.scene.read_bytes() if args.scene else None, args.min_requests)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
