#!/usr/bin/env python3
"""Soak and fault test of ntscontactd on 127.0.0.1 (issue 7), bounded in time.

    tests/load/soak.py [--duration 60] [--connections 16] [--build-dir build]
                       [--json-out FILE] [--no-faults] [--no-sigterm] [--seed N]

What it does:
  1. Builds a set of request bodies: the example scenes, the fuzzer's seeds,
     jittered variants of them (valid or not, whatever they turn out to be),
     the malformed catalogue (fuzz/corpus/cat-*.json) and truncated scenes.
     The answer to each comes from the CLI (`ntscontact -`): the oracle.
  2. Starts `ntscontactd --port 0 --quiet` (loopback only) and runs
     `--connections` keep-alive clients posting random bodies for `--duration`
     seconds; every answer is compared with the CLI's: a 200 body must equal
     the CLI's output (elapsed_ms aside), an error must carry the CLI's code
     and JSON pointer with a 4xx status. Latency of every request is kept.
  3. Meanwhile fault clients (raw sockets, bounded loops): a client that
     disconnects mid-upload, one that sends garbage bytes, one that uploads a
     body very slowly, one that announces a huge Content-Length, one with an
     oversized header, one that connects and sends nothing, and requests with
     a wrong method, path or content type.
  4. Samples the daemon's resident memory (VmRSS) every 0.5 s.
  5. SIGTERM in the middle of the load: a few requests are held in flight
     (headers and half a body sent, seen in /v1/health), SIGTERM goes out, the
     rest of their bodies follow; each must still get its full, right answer,
     the load clients keep going, and the daemon must exit with status 0.

Prints a summary and, with --json-out, the figures as JSON. Exits 1 when any
answer was wrong, any 5xx was seen, a load request failed before SIGTERM, a
held request did not complete, or the daemon did not exit 0.
The same module runs for 12 s inside the test suite (tests/python/test_reliability.py).
"""
import argparse
import http.client
import json
import os
import pathlib
import random
import re
import signal
import socket
import subprocess
import sys
import threading
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
ELAPSED = re.compile(rb'"elapsed_ms":\s*[-+0-9.eE]+')
CLI_ERROR = re.compile(r'^ntscontact: (\S+) at "(.*)": ')
HOST = "127.0.0.1"


def normalize(body):
    """The body with the one field that differs between two runs blanked."""
    return ELAPSED.sub(b'"elapsed_ms":#', body.strip())


class Case:
    """A request body and the CLI's answer to it: status 200 and the
    normalised body, or an error code and pointer."""

    def __init__(self, name, body, ok, expect=None, code=None, pointer=None):
        self.name, self.body, self.ok = name, body, ok
        self.expect, self.code, self.pointer = expect, code, pointer


def oracle(cli, name, body):
    proc = subprocess.run([str(cli), "-"], input=body, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, timeout=300)
    if proc.returncode == 0:
        return Case(name, body, True, expect=normalize(proc.stdout))
    line = proc.stderr.decode(errors="replace").splitlines()
    m = CLI_ERROR.match(line[0]) if line else None
    if proc.returncode != 3 or m is None:
        raise RuntimeError(f"the CLI failed on {name}: exit {proc.returncode}: {proc.stderr[:500]!r}")
    # the CLI writes the pointer as a JSON string's contents (a newline in a key as \u000a)
    return Case(name, body, False, code=m.group(1), pointer=json.loads('"' + m.group(2) + '"'))


def jitter(scene, rng, amount):
    s = json.loads(json.dumps(scene))
    for body in s.get("bodies", []):
        nodes = body.get("nodes")
        if isinstance(nodes, list):
            for p in nodes:
                if isinstance(p, list) and len(p) == 2 and all(isinstance(v, (int, float)) for v in p):
                    p[0] += rng.uniform(-amount, amount)
                    p[1] += rng.uniform(-amount, amount)
    opts = s.setdefault("options", {})
    if isinstance(opts, dict):
        opts["outputs"] = rng.choice([["forces", "energy", "virial"],
                                      ["forces", "energy", "virial", "contacts", "gaps"],
                                      [], ["contacts"]])
    return s


def build_cases(cli, rng, variants=3, log=print):
    """Request bodies with their CLI answers (valid and invalid)."""
    sources = sorted((REPO / "examples").glob("*.json")) + sorted((REPO / "fuzz" / "seeds").glob("*.json"))
    raw = []
    for p in sources:
        data = p.read_bytes()
        raw.append((p.stem, data))
        try:
            scene = json.loads(data)
        except ValueError:
            continue
        for k in range(variants):
            amount = rng.choice([1e-3, 1e-2, 5e-2])
            raw.append((f"{p.stem}~{k}", json.dumps(jitter(scene, rng, amount)).encode()))
        cut = rng.randrange(1, max(2, len(data) - 1))
        raw.append((f"{p.stem}/truncated", data[:cut]))
    for p in sorted((REPO / "fuzz" / "corpus").glob("cat-*.json")):
        raw.append((p.stem, p.read_bytes()))
    cases = [oracle(cli, name, body) for name, body in raw]
    log(f"soak: {len(cases)} request bodies, {sum(c.ok for c in cases)} valid, "
        f"{sum(not c.ok for c in cases)} invalid (answers from the CLI)")
    return cases


def build_session_cases(cli, rng, steps=6):
    """Sessions to step: for a few example scenes, the scene (to create the
    session) and `steps` jittered position sets, each a step body
    {"positions": ...} with the CLI's answer to the whole scene at those
    positions (a step answers exactly what a full scene would)."""
    out = []
    for name in ("two_disks", "jittered_packing"):
        path = REPO / "examples" / f"{name}.json"
        if not path.exists():
            continue
        scene = json.loads(path.read_bytes())
        cases = []
        for k in range(steps):
            moved = jitter(scene, rng, rng.choice([1e-3, 1e-2]))
            moved["options"] = scene.get("options", {})  # a step keeps the session's options
            positions = [p for b in moved["bodies"] for p in b["nodes"]]
            full = oracle(cli, f"{name}@{k}", json.dumps(moved).encode())
            cases.append(Case(f"session {name} step {k}", json.dumps({"positions": positions}).encode(), full.ok,
                              expect=full.expect, code=full.code, pointer=full.pointer))
        out.append((json.dumps(scene).encode(), cases))
    return out


class Session:
    """A session the load steps: created from `scene`, created again when
    the daemon no longer knows it (evicted: --max-sessions)."""

    def __init__(self, scene, cases):
        self.scene, self.cases, self.id = scene, cases, None

    def path(self, conn):
        if self.id is None:
            conn.request("POST", "/v1/scenes", body=self.scene, headers={"Content-Type": "application/json"})
            resp = conn.getresponse()
            data = resp.read()
            if resp.status != 201:
                raise http.client.HTTPException(f"session not created: {resp.status} {data[:200]!r}")
            self.id = json.loads(data)["id"]
        return f"/v1/scenes/{self.id}/contact"


def check(case, status, data):
    """None when the answer is the CLI's, else what is wrong."""
    if case.ok:
        if status != 200:
            return f"status {status}, the CLI answered 200: {data[:300]!r}"
        if normalize(data) != case.expect:
            return "the body differs from the CLI's output"
        return None
    if not 400 <= status < 500:
        return f"status {status} for an invalid scene ({case.code})"
    try:
        err = json.loads(data)["error"]
    except (ValueError, KeyError, TypeError):
        return f"not an error document: {data[:300]!r}"
    if err.get("code") != case.code:
        return f"code {err.get('code')!r}, the CLI said {case.code!r}"
    if err.get("pointer", "") != case.pointer:
        return f"pointer {err.get('pointer')!r}, the CLI said {case.pointer!r}"
    return None


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.requests = 0
        self.by_status = {}
        self.latencies = []
        self.wrong = []
        self.transport_before = []  # load requests that failed before SIGTERM
        self.transport_after = 0    # ... and after it (expected: the daemon goes away)
        self.server_errors = 0
        self.faults = {}
        self.fault_problems = []
        self.sigterm_at = None
        self.refused_after_sigterm = 0
        self.latencies_after = []
        self.idle_reconnects = 0
        self.session_steps = 0
        self.sessions_recreated = 0

    def record(self, case, status, data, latency):
        problem = check(case, status, data)
        with self.lock:
            if status == 503 and self.sigterm_at is not None and b'"overloaded"' in data:
                # Shutting down: a request the daemon had not started yet is
                # refused with 503 (never cut, never answered wrong).
                self.refused_after_sigterm += 1
                return
            self.requests += 1
            self.by_status[status] = self.by_status.get(status, 0) + 1
            if self.sigterm_at is None:  # the figures describe the steady load
                self.latencies.append(latency)
            else:
                self.latencies_after.append(latency)
            if status >= 500:
                self.server_errors += 1
            if problem is not None:
                self.wrong.append(f"{case.name}: {problem}")

    def transport(self, exc):
        with self.lock:
            if self.sigterm_at is None:
                self.transport_before.append(repr(exc))
            else:
                self.transport_after += 1

    def fault(self, kind, outcome):
        with self.lock:
            d = self.faults.setdefault(kind, {})
            d[outcome] = d.get(outcome, 0) + 1


def load_client(port, cases, seed, stop, stats, idle_timeout=None, session=None):
    """Posts random bodies on one keep-alive connection (with `session`, the
    steps of that session: `cases` are its step bodies). A connection the
    daemon closed because it sat idle for its --timeout (this client was
    starved of CPU that long) is not a lost request: the request is sent again
    on a new connection, as HTTP clients do, and counted apart. Any other
    transport failure before SIGTERM is a lost request."""
    rng = random.Random(seed)
    conn = http.client.HTTPConnection(HOST, port, timeout=120)
    last_done = None  # when the last answer on `conn` completed
    retry = None
    while not stop.is_set():
        case = retry if retry is not None else rng.choice(cases)
        t0 = time.perf_counter()
        started = time.monotonic()
        try:
            path = session.path(conn) if session is not None else "/v1/contact"
            conn.request("POST", path, body=case.body, headers={"Content-Type": "application/json"})
            resp = conn.getresponse()
            data = resp.read()
        except (OSError, http.client.HTTPException) as exc:
            conn.close()
            idle = None if last_done is None else started - last_done
            if (retry is None and idle_timeout is not None and idle is not None and idle >= 0.9 * idle_timeout
                    and isinstance(exc, (BrokenPipeError, ConnectionResetError, http.client.RemoteDisconnected))):
                with stats.lock:
                    stats.idle_reconnects += 1
                retry = case
            else:
                stats.transport(exc)
                retry = None
                if stats.sigterm_at is not None:
                    time.sleep(0.05)  # the daemon is going away: do not spin
            conn = http.client.HTTPConnection(HOST, port, timeout=120)
            last_done = None
            continue
        retry = None
        last_done = time.monotonic()
        if session is not None:
            if resp.status == 404 and b'"unknown_scene"' in data:  # evicted: create it again, step again
                session.id = None
                retry = case
                with stats.lock:
                    stats.sessions_recreated += 1
                continue
            with stats.lock:
                stats.session_steps += 1
        stats.record(case, resp.status, data, time.perf_counter() - t0)
        if resp.will_close:
            conn.close()
            conn = http.client.HTTPConnection(HOST, port, timeout=120)
            last_done = None
    conn.close()


# ------------------------------------------------------------ fault clients

def _connect(port, timeout=10):
    s = socket.create_connection((HOST, port), timeout=timeout)
    return s


def _read_status(sock):
    """The status code of the answer on `sock`, or None when the peer closed
    (or reset) without one."""
    data = b""
    try:
        while b"\r\n" not in data and len(data) < 65536:
            chunk = sock.recv(4096)
            if not chunk:
                break
            data += chunk
    except OSError:
        pass
    m = re.match(rb"HTTP/1\.[01] (\d{3})", data)
    return int(m.group(1)) if m else None


def _post_head(length, ctype="application/json", path="/v1/contact", extra=""):
    return (f"POST {path} HTTP/1.1\r\nHost: {HOST}\r\nContent-Type: {ctype}\r\n"
            f"Content-Length: {length}\r\n{extra}\r\n").encode()


def fault_disconnect(port, body, stop, stats, rng):
    while not stop.is_set():
        try:
            s = _connect(port)
            s.sendall(_post_head(len(body)) + body[: rng.randrange(0, max(1, len(body) // 2))])
            s.close()
            stats.fault("disconnect_mid_upload", "sent")
        except OSError:
            stats.fault("disconnect_mid_upload", "connect_failed")
        stop.wait(0.05)


def fault_garbage(port, stop, stats, rng):
    while not stop.is_set():
        junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 600)))
        if rng.random() < 0.5:
            junk += b"\r\n\r\n"
        try:
            s = _connect(port)
            s.sendall(junk)
            try:
                s.shutdown(socket.SHUT_WR)
            except OSError:
                pass
            status = _read_status(s)
            s.close()
            outcome = "closed" if status is None else str(status)
            if status is not None and status >= 500:
                stats.fault_problems.append(f"garbage got {status}")
            stats.fault("garbage", outcome)
        except OSError:
            stats.fault("garbage", "reset")
        stop.wait(0.05)


def fault_slow(port, body, stop, stats, step=0.2, max_seconds=None):
    """Uploads the body a few bytes at a time; the daemon must cut it off (its
    upload budget is --timeout) rather than let it hold a connection forever."""
    while not stop.is_set():
        started = time.monotonic()
        try:
            s = _connect(port, timeout=60)
            s.sendall(_post_head(len(body)))
            sent = 0
            cut = False
            while sent < len(body) and not stop.is_set():
                if max_seconds is not None and time.monotonic() - started > max_seconds:
                    break
                try:
                    s.sendall(body[sent:sent + 4])
                except OSError:
                    cut = True
                    break
                sent += 4
                stop.wait(step)
            if sent >= len(body):
                stats.fault("slow_upload", "finished")  # the daemon let a trickle through
            elif cut:
                stats.fault("slow_upload", "cut_off")
            else:
                # stopped by us: see whether the daemon had answered or closed already
                s.settimeout(1.0)
                status = _read_status(s)
                stats.fault("slow_upload", "cut_off" if status is not None or _closed(s) else "still_open")
            s.close()
        except OSError:
            stats.fault("slow_upload", "cut_off")


def _closed(sock):
    try:
        sock.settimeout(0.5)
        return sock.recv(1) == b""
    except (socket.timeout, BlockingIOError):
        return False
    except OSError:
        return True


def fault_misc(port, stop, stats, rng):
    """Requests that must get their own 4xx: wrong method, path, media type,
    a huge announced body, an oversized header, an idle connection."""
    kinds = ["method", "path", "media_type", "huge_length", "big_header", "idle"]
    while not stop.is_set():
        kind = rng.choice(kinds)
        try:
            s = _connect(port)
            if kind == "method":
                s.sendall(f"GET /v1/contact HTTP/1.1\r\nHost: {HOST}\r\nConnection: close\r\n\r\n".encode())
            elif kind == "path":
                s.sendall(f"GET /v1/nothing HTTP/1.1\r\nHost: {HOST}\r\nConnection: close\r\n\r\n".encode())
            elif kind == "media_type":
                s.sendall(_post_head(2, ctype="text/plain", extra="Connection: close\r\n") + b"{}")
            elif kind == "huge_length":
                s.sendall(_post_head(1 << 40))
            elif kind == "big_header":
                s.sendall(f"GET /v1/health HTTP/1.1\r\nHost: {HOST}\r\nX-Big: {'a' * 200000}\r\n\r\n".encode())
            else:
                stop.wait(1.0)
                s.close()
                stats.fault("idle", "closed_by_us")
                continue
            status = _read_status(s)
            s.close()
            stats.fault(kind, "closed" if status is None else str(status))
            if status is not None and status >= 500:
                stats.fault_problems.append(f"{kind} got {status}")
            want = {"method": 405, "path": 404, "media_type": 415, "huge_length": 413}.get(kind)
            if want is not None and status is not None and status != want:
                stats.fault_problems.append(f"{kind}: status {status}, expected {want}")
        except OSError:
            stats.fault(kind, "reset")
        stop.wait(0.05)


# ------------------------------------------------------------ the daemon

def rss_kib(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def start_daemon(binary, log_path, flags):
    log = open(log_path, "wb")
    proc = subprocess.Popen([str(binary), "--host", HOST, "--port", "0", *flags],
                            stdout=subprocess.PIPE, stderr=log, stdin=subprocess.DEVNULL)
    log.close()
    line = proc.stdout.readline().decode(errors="replace").strip()
    if not line.startswith("ntscontactd listening on "):
        proc.kill()
        proc.wait()
        raise RuntimeError(f"ntscontactd did not start: {line!r}")
    return proc, int(line.rsplit(":", 1)[1])


def health(port):
    conn = http.client.HTTPConnection(HOST, port, timeout=10)
    try:
        conn.request("GET", "/v1/health")
        resp = conn.getresponse()
        return resp.status, json.loads(resp.read())
    finally:
        conn.close()


def held_request(port, case, started, finish, results, idx):
    """A request the daemon has started before SIGTERM: headers with
    `Expect: 100-continue`, so the daemon's "100 Continue" proves it has taken
    the request in (its handler ran: the request counts as in flight), then
    half the body; wait for `finish` (SIGTERM has gone out), then the rest."""
    try:
        s = _connect(port, timeout=120)
        half = len(case.body) // 2
        s.sendall(_post_head(len(case.body), extra="Connection: close\r\nExpect: 100-continue\r\n"))
        interim = b""
        while b"\r\n\r\n" not in interim and len(interim) < 4096:
            chunk = s.recv(4096)
            if not chunk:
                break
            interim += chunk
        if not interim.startswith(b"HTTP/1.1 100"):
            results[idx] = f"no 100 Continue before SIGTERM: {interim[:200]!r}"
            started.release()
            return
        s.sendall(case.body[:half])
        started.release()
        finish.wait(60)
        s.sendall(case.body[half:])
        data = interim.partition(b"\r\n\r\n")[2]
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
        s.close()
        head, _, body = data.partition(b"\r\n\r\n")
        m = re.match(rb"HTTP/1\.[01] (\d{3})", head)
        status = int(m.group(1)) if m else None
        results[idx] = check(case, status, body) if status is not None else f"no answer: {data[:200]!r}"
    except OSError as exc:
        started.release()
        results[idx] = f"transport error: {exc!r}"


def percentile(values, q):
    if not values:
        return None
    v = sorted(values)
    k = min(len(v) - 1, max(0, int(round(q / 100.0 * (len(v) - 1)))))
    return v[k]


def run(build_dir, duration=60.0, connections=16, faults=True, sigterm=True, seed=7,
        daemon_flags=("--quiet",), log=print, log_path=None, variants=3, held=4, sessions=4):
    build_dir = pathlib.Path(build_dir)
    cli, daemon_bin = build_dir / "bin" / "ntscontact", build_dir / "bin" / "ntscontactd"
    rng = random.Random(seed)
    cases = build_cases(cli, rng, variants=variants, log=log)
    valid = [c for c in cases if c.ok]
    session_cases = build_session_cases(cli, rng) if sessions else []
    log_path = pathlib.Path(log_path or (build_dir / "soak-daemon.log"))
    flags = list(daemon_flags)
    idle_timeout = 30.0  # the daemon's default --timeout
    for k, f in enumerate(flags[:-1]):
        if f == "--timeout":
            idle_timeout = float(flags[k + 1])
    proc, port = start_daemon(daemon_bin, log_path, flags)
    stats = Stats()
    stop_load, stop_faults = threading.Event(), threading.Event()
    rss = []
    rss_stop = threading.Event()

    def sample():
        t0 = time.monotonic()
        while not rss_stop.is_set():
            r = rss_kib(proc.pid)
            if r is not None:
                rss.append((time.monotonic() - t0, r))
            rss_stop.wait(0.5)

    threads = [threading.Thread(target=sample, daemon=True)]
    for i in range(connections):
        threads.append(threading.Thread(target=load_client,
                                        args=(port, cases, seed * 1000 + i, stop_load, stats, idle_timeout),
                                        daemon=True))
    for i in range(sessions if session_cases else 0):
        scene, steps = session_cases[i % len(session_cases)]
        threads.append(threading.Thread(target=load_client,
                                        args=(port, steps, seed * 2000 + i, stop_load, stats, idle_timeout,
                                              Session(scene, steps)), daemon=True))
    fault_threads = []
    if faults:
        small = min(valid, key=lambda c: len(c.body)).body
        frng = random.Random(seed + 1)
        fault_threads = [
            threading.Thread(target=fault_disconnect, args=(port, valid[0].body, stop_faults, stats, frng), daemon=True),
            threading.Thread(target=fault_garbage, args=(port, stop_faults, stats, random.Random(seed + 2)), daemon=True),
            threading.Thread(target=fault_slow, args=(port, small * 40, stop_faults, stats), daemon=True),
            threading.Thread(target=fault_misc, args=(port, stop_faults, stats, random.Random(seed + 3)), daemon=True),
        ]
    t_start = time.monotonic()
    for t in threads + fault_threads:
        t.start()
    time.sleep(duration)
    stop_faults.set()
    for t in fault_threads:
        t.join(timeout=30)
    rss_before_stop = rss_kib(proc.pid)
    hstatus, hdoc = health(port)
    exit_code = None
    held_results = []
    seen = 0
    if sigterm:
        # Requests held in flight across SIGTERM, the load still running.
        started, finish = threading.Semaphore(0), threading.Event()
        held_results = [None] * held
        holders = [threading.Thread(target=held_request,
                                    args=(port, valid[i % len(valid)], started, finish, held_results, i), daemon=True)
                   for i in range(held)]
        for t in holders:
            t.start()
        for _ in holders:
            started.acquire(timeout=30)
        _, doc = health(port)
        seen = doc.get("requests_in_flight", 0)  # reported: held + load + this one
        with stats.lock:
            stats.sigterm_at = time.monotonic()
        os.kill(proc.pid, signal.SIGTERM)
        time.sleep(0.2)
        finish.set()
        for t in holders:
            t.join(timeout=60)
        try:
            exit_code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            exit_code = "did not exit within 60 s of SIGTERM"
        stop_load.set()
    else:
        stop_load.set()
    for t in threads[1:]:
        t.join(timeout=60)
    rss_stop.set()
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            exit_code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            exit_code = "killed"
    elapsed = time.monotonic() - t_start
    lat_ms = [1e3 * x for x in stats.latencies]
    warm = [r for t, r in rss if t >= min(5.0, duration / 4)]
    base = warm[0] if warm else (rss[0][1] if rss else None)
    result = {
        "duration_s": round(elapsed, 1),
        "connections": connections,
        "bodies": len(cases),
        "requests": stats.requests,
        "requests_per_s": round(stats.requests / max(duration, 1e-9), 1),
        "by_status": {str(k): v for k, v in sorted(stats.by_status.items())},
        "wrong_answers": len(stats.wrong),
        "wrong_examples": stats.wrong[:10],
        "server_errors_5xx": stats.server_errors,
        "transport_errors_before_sigterm": len(stats.transport_before),
        "transport_errors_examples": stats.transport_before[:10],
        "transport_errors_after_sigterm": stats.transport_after,
        "refused_503_after_sigterm": stats.refused_after_sigterm,
        "idle_reconnects": stats.idle_reconnects,
        "session_clients": sessions if session_cases else 0,
        "session_steps": stats.session_steps,
        "sessions_recreated": stats.sessions_recreated,
        "latency_ms": {"p50": percentile(lat_ms, 50), "p90": percentile(lat_ms, 90),
                       "p99": percentile(lat_ms, 99), "p999": percentile(lat_ms, 99.9),
                       "max": max(lat_ms) if lat_ms else None,
                       "over_1s": sum(1 for x in lat_ms if x > 1000.0),
                       "max_after_sigterm": 1e3 * max(stats.latencies_after) if stats.latencies_after else None},
        "rss_kib": {"start": rss[0][1] if rss else None, "after_warmup": base,
                    "before_stop": rss_before_stop, "max": max((r for _, r in rss), default=None)},
        "rss_growth_kib_after_warmup": (rss_before_stop - base) if (rss_before_stop and base) else None,
        "faults": stats.faults,
        "fault_problems": stats.fault_problems[:10],
        "health_before_stop": {"status": hstatus, "requests_served": hdoc.get("requests_served")},
        "held_in_flight_at_sigterm": held if sigterm else 0,
        "in_flight_seen_at_sigterm": seen if sigterm else 0,
        "held_results": held_results,
        "daemon_exit": exit_code,
    }
    return result


def failures(result, sigterm=True):
    bad = []
    if result["requests"] == 0:
        bad.append("no request was answered")
    if result["session_clients"] and result["session_steps"] == 0:
        bad.append("no session step was answered")
    if result["wrong_answers"]:
        bad.append(f"{result['wrong_answers']} wrong answers, e.g. {result['wrong_examples']}")
    if result["server_errors_5xx"]:
        bad.append(f"{result['server_errors_5xx']} 5xx answers")
    if result["transport_errors_before_sigterm"]:
        bad.append(f"{result['transport_errors_before_sigterm']} load requests failed before SIGTERM: "
                   f"{result['transport_errors_examples']}")
    if result["fault_problems"]:
        bad.append(f"fault clients: {result['fault_problems']}")
    if result["health_before_stop"]["status"] != 200:
        bad.append("/v1/health failed after the faults")
    if sigterm and any(r is not None for r in result["held_results"]):
        bad.append(f"requests in flight at SIGTERM did not complete right: {result['held_results']}")
    if result["daemon_exit"] != 0:
        bad.append(f"daemon exit status {result['daemon_exit']}")
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--connections", type=int, default=16)
    ap.add_argument("--sessions", type=int, default=4, help="clients stepping a session each (besides --connections)")
    ap.add_argument("--build-dir", default=os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--no-faults", action="store_true")
    ap.add_argument("--no-sigterm", action="store_true")
    ap.add_argument("--json-out")
    ap.add_argument("--daemon-flag", action="append", default=[],
                    help="extra flag for ntscontactd (repeat), e.g. --daemon-flag=--threads=2")
    args = ap.parse_args()
    flags = ["--quiet", "--timeout", "5", *args.daemon_flag]
    result = run(args.build_dir, duration=args.duration, connections=args.connections,
                 faults=not args.no_faults, sigterm=not args.no_sigterm, seed=args.seed, daemon_flags=flags,
                 sessions=args.sessions)
    text = json.dumps(result, indent=2)
    print(text)
    if args.json_out:
        pathlib.Path(args.json_out).write_text(text + "\n")
    bad = failures(result, sigterm=not args.no_sigterm)
    for b in bad:
        print("soak: FAIL:", b, file=sys.stderr)
    print("soak: %s" % ("FAILED" if bad else "passed"), file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
