#!/usr/bin/env python3
"""Does a long evaluation stall other connections? (the threading decision)

While BUSY client threads post a large scene in a loop, one more client asks
GET /v1/health on a fresh connection every 50 ms and records its latency.
Bounded: --seconds of load (default 10), 127.0.0.1 only, standard library only.

    stall.py PORT large.json [--busy 2] [--seconds 10]
"""
import argparse
import http.client
import statistics
import threading
import time


def post_loop(port, body, stop, counts):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    while not stop.is_set():
        conn.request("POST", "/v1/contact", body, {"Content-Type": "application/json"})
        r = conn.getresponse()
        r.read()
        counts.append(r.status)
    conn.close()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("port", type=int)
    ap.add_argument("scene")
    ap.add_argument("--busy", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=10.0)
    a = ap.parse_args()
    body = open(a.scene, "rb").read()
    stop, counts = threading.Event(), []
    threads = [threading.Thread(target=post_loop, args=(a.port, body, stop, counts)) for _ in range(a.busy)]
    for t in threads:
        t.start()
    time.sleep(0.5)
    lat = []
    end = time.monotonic() + a.seconds
    while time.monotonic() < end:
        t0 = time.monotonic()
        conn = http.client.HTTPConnection("127.0.0.1", a.port, timeout=120)
        conn.request("GET", "/v1/health")
        conn.getresponse().read()
        conn.close()
        lat.append(1e3 * (time.monotonic() - t0))
        time.sleep(0.05)
    stop.set()
    for t in threads:
        t.join()
    lat.sort()
    q = lambda p: lat[min(len(lat) - 1, int(p * len(lat)))]
    print(f"STALL busy={a.busy} large_posts={len(counts)} health_n={len(lat)} "
          f"p50_ms={q(0.5):.2f} p90_ms={q(0.9):.2f} p99_ms={q(0.99):.2f} max_ms={lat[-1]:.2f} "
          f"mean_ms={statistics.mean(lat):.2f}")


if __name__ == "__main__":
    main()
