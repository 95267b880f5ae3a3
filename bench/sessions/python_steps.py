#!/usr/bin/env python3
"""Per-step cost of a solver loop through the Python client (issue 10, item 9).

Two kinds of scene, each stepped with every node moved:
  - square packings of pressed 64-node disks (bench/load/make_scene.py) of about
    1e3, 1e4, 1e5 (and 1e6) surface nodes, as loops;
  - an FEM-like scene of 66k nodes: four disks meshed with linear triangles
    (structured polar meshes), pressed together, sent as triangles, as an FEM
    code coupled to the service does (every mesh node, interior ones included),
    stepped with every node and with a surface exchange (?nodes=surface: the
    surface nodes' positions and forces alone).

For each, the wall time of one step as a user writes it:
  full     scene.set_nodes(...) for every body, then client.contact(scene)
           (the JSON of the whole scene encoded in Python, sent, decoded, and the
           JSON answer parsed into numpy);
  session  s.contact(x) then res.force_array() (raw float64 both ways).
Medians of the repeats, one keep-alive connection, a daemon started here with
one evaluation thread.

    bench/sessions/python_steps.py [--sizes 4,12,40] [--repeats 7] [--out docs/benchmarks.md]

Writes bench/results/sessions_python.csv and replaces the section "Sessions
through the Python client" of docs/benchmarks.md.
"""
import argparse
import http.client
import json
import math
import os
import pathlib
import statistics
import sys
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
sys.path.insert(0, str(REPO / "bench" / "load"))
sys.path.insert(0, str(REPO / "bench" / "sessions"))
from make_scene import scene as make_scene  # noqa: E402
from common import provenance, start_daemon, write_results  # noqa: E402

import ntscontact  # noqa: E402
from ntscontact.mesh import disk_mesh  # noqa: E402

SECTION = "## Sessions through the Python client"


def fem_scene(total_nodes=66000):
    # four disks of equal size: 1 + 3 r (r + 1) nodes each
    per = total_nodes // 4
    rings = math.ceil((-3 + math.sqrt(9 + 12 * (per - 1))) / 6)
    scene = ntscontact.Scene(penalty=100.0, alpha=0.2, search_radius=0.01, outputs=["forces", "energy", "virial"])
    for i, (cx, cy) in enumerate([(0, 0), (1.995, 0), (0, 1.995), (1.995, 1.995)]):
        nodes, tri = disk_mesh(1.0, rings, cx, cy)
        scene.add_body(nodes, triangles=tri, id=f"disk-{i}")
    return scene


def fem_surface_scene(total_nodes=66000):
    """fem_scene's four disks as only their outer rings (loops): the same
    surfaces, what a step would carry if it sent the surface nodes alone."""
    per = total_nodes // 4
    rings = math.ceil((-3 + math.sqrt(9 + 12 * (per - 1))) / 6)
    scene = ntscontact.Scene(penalty=100.0, alpha=0.2, search_radius=0.01, outputs=["forces", "energy", "virial"])
    for i, (cx, cy) in enumerate([(0, 0), (1.995, 0), (0, 1.995), (1.995, 1.995)]):
        nodes, _ = disk_mesh(1.0, rings, cx, cy)
        scene.add_body(nodes[-6 * rings:], id=f"disk-{i}")  # disk_mesh: the outer ring last, counter-clockwise
    return scene


def packing_scene(side):
    doc = make_scene(side, 64)
    doc["options"]["outputs"] = ["forces", "energy", "virial"]
    return ntscontact.Scene.from_dict(doc)


def measure(client, name, scene, repeats, exchange="all"):
    ids = scene.body_ids
    counts = [scene.body(i).node_count for i in ids]
    x0 = np.concatenate([scene.body(i).nodes for i in ids])
    rng = np.random.default_rng(len(x0))
    frames = [x0 + rng.normal(scale=1e-5, size=x0.shape) for _ in range(repeats)]
    offsets = np.concatenate([[0], np.cumsum(counts)])

    def full(i):
        for k, body_id in enumerate(ids):
            scene.set_nodes(body_id, frames[i][offsets[k]:offsets[k + 1]])
        return client.contact(scene).force_array()

    request_bytes = len(scene.to_json())
    full(0)
    t_full = []
    for i in range(repeats):
        t0 = time.perf_counter()
        f_full = full(i)
        t_full.append(time.perf_counter() - t0)
    # The session's steps two ways on one daemon, in interleaved rounds: the
    # client as it is (its own kept connection, ntscontact._wire) and the
    # same client on urllib3's pool (wire=False): the same steps, the same
    # bytes, the forces checked equal bit for bit.
    pool_client = ntscontact.Client(client.base_url, timeout=600, wire=False)
    t_sess, t_daemon, ratio, ratio_pool, t_pool = [], [], [], [], []
    phases = {"receiving": 0.0, "handling": 0.0, "sending": 0.0}
    with client.session(scene, exchange=exchange) as s, pool_client.session(scene, exchange=exchange) as sp:
        s.contact(frames[0])
        sp.contact(frames[0])
        for _ in range(3):
            h0 = health(client)
            for i in range(repeats):
                t0 = time.perf_counter()
                res = s.contact(frames[i])
                f_sess = res.force_array()
                t_sess.append(time.perf_counter() - t0)
                # the daemon's own time of the step (NTS-Elapsed-Ms: positions in, evaluation, answer out)
                t_daemon.append(1e-3 * res.summary.elapsed_ms)
                ratio.append(t_sess[-1] / t_daemon[-1] if t_daemon[-1] > 0 else float("nan"))
            h1 = health(client)
            for k in phases:  # the daemon's own account of each step's phases (/v1/health time_s)
                phases[k] += (h1["time_s"][k] - h0["time_s"][k]) / (3 * repeats)
            for i in range(repeats):
                t0 = time.perf_counter()
                res_pool = sp.contact(frames[i])
                f_pool = res_pool.force_array()
                t_pool.append(time.perf_counter() - t0)
                ratio_pool.append(t_pool[-1] / (1e-3 * res_pool.summary.elapsed_ms))
            assert np.array_equal(f_pool, f_sess), "the two paths disagree"
        # The floor under the client: the same steps as bare http.client calls
        # (the same bytes both ways, no client library, no numpy result): the
        # steps' wall time over the daemon's own time.
        raw_ratio = []
        host, port = client.base_url.split("//", 1)[1].split(":")
        conn = http.client.HTTPConnection(host, int(port), timeout=600)
        heads = {"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"}
        rows = s.surface if s.surface is not None else slice(None)
        query = "?nodes=surface" if s.surface is not None else ""
        sent = [np.ascontiguousarray(f[rows]) for f in frames]
        for i in range(repeats):
            t0 = time.perf_counter()
            conn.request("POST", f"/v1/scenes/{s.id}/contact{query}", body=memoryview(sent[i]).cast("B"),
                         headers=heads)
            r = conn.getresponse()
            f_raw = np.frombuffer(r.read(), dtype="<f8").reshape(-1, 2)
            raw_ratio.append((time.perf_counter() - t0) / (1e-3 * float(r.getheader("NTS-Elapsed-Ms"))))
        conn.close()
        assert np.array_equal(f_raw, f_sess[rows]), "bare http.client and the client disagree"
        sent_nodes = len(sent[0])
    pool_client.close()
    assert np.array_equal(f_full, f_sess), "session and full call disagree"
    row = {"scene": name, "nodes": int(len(x0)), "surface_nodes": int(res.summary.surface_nodes), "full_request_mb": request_bytes / 1e6,
           "session_request_mb": 16 * sent_nodes / 1e6, "exchange": exchange, "full_ms": 1e3 * statistics.median(t_full),
           "session_ms": 1e3 * statistics.median(t_sess), "daemon_ms": 1e3 * statistics.median(t_daemon),
           "session_over_daemon": statistics.median(ratio), "session_over_daemon_min": min(ratio),
           "session_over_daemon_max": max(ratio), "bare_over_daemon": statistics.median(raw_ratio),
           "pool_ms": 1e3 * statistics.median(t_pool), "pool_over_daemon": statistics.median(ratio_pool),
           "receiving_ms": 1e3 * phases["receiving"], "handling_ms": 1e3 * phases["handling"],
           "sending_ms": 1e3 * phases["sending"]}
    row["speedup"] = row["full_ms"] / row["session_ms"]
    return row


def health(client):
    """The daemon's /v1/health (its time_s: seconds spent receiving bodies,
    handling, sending answers, summed over the requests it served)."""
    host, port = client.base_url.split("//", 1)[1].split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=60)
    conn.request("GET", "/v1/health")
    doc = json.loads(conn.getresponse().read())
    conn.close()
    return doc


def markdown(rows, repeats):
    lines = [SECTION, "",
             "Wall time of one solver step as a Python user writes it (`bench/sessions/python_steps.py`, median",
             f"of {repeats} steps that each move every node, one evaluation thread, loopback): **full** is",
             "`scene.set_nodes(...)` for every body then `client.contact(scene)` (the whole scene as JSON, the",
             "JSON answer parsed into numpy); **session** is `s.contact(x).force_array()` (raw float64 both",
             "ways). The forces of the two are checked equal, bit for bit, in the same run. The FEM scene is four",
             "disks of linear triangles sent as triangles, every mesh node included, as an FEM code sends them.",
             "**daemon** is the daemon's own time of the session step (its `NTS-Elapsed-Ms`: the positions read",
             "and checked, the evaluation, the answer written), and **session / daemon** the step's wall time over",
             "it, step by step (median; range): what the client and the loopback add (target, issue 27: at most",
             "1.3 on the FEM scene). The client sends a step on a kept connection of its own",
             "(`ntscontact._wire`: the head and the positions in one `sendmsg` from the array's memory, the answer",
             "read into one buffer, the step's copy of the positions made while the daemon computes);",
             "**urllib3 / daemon** is the same client on urllib3's pool (`Client(wire=False)`, what it used",
             "before), in interleaved rounds with it (3 rounds of the same steps, the forces checked equal bit",
             "for bit). **bare / daemon** is the same steps sent as bare `http.client` calls (the same bytes, no",
             "client library, no numpy result). **daemon: in / out** is the daemon's own account of a step",
             "outside its `NTS-Elapsed-Ms` (`/v1/health` `time_s`, per step): receiving the request's body",
             "and sending the answer; **floor** is (receiving + handling + sending) / daemon, the ratio a client",
             "that cost nothing would see.", "", provenance(),
             "", "| scene | nodes | full: request | full | session: request | session | daemon | session / daemon "
             "| urllib3 / daemon | bare / daemon | daemon: in / out | floor | speed-up |",
             "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        floor = (r["receiving_ms"] + r["handling_ms"] + r["sending_ms"]) / r["daemon_ms"]
        lines.append(f"| {r['scene']} | {r['nodes']:,} | {r['full_request_mb']:.2f} MB | {r['full_ms']:.1f} ms "
                     f"| {r['session_request_mb']:.2f} MB | {r['session_ms']:.2f} ms | {r['daemon_ms']:.2f} ms "
                     f"| {r['session_over_daemon']:.2f} ({r['session_over_daemon_min']:.2f}-"
                     f"{r['session_over_daemon_max']:.2f}) | {r['pool_over_daemon']:.2f} | {r['bare_over_daemon']:.2f} "
                     f"| {r['receiving_ms']:.2f} / {r['sending_ms']:.2f} ms | {floor:.2f} | {r['speedup']:.1f}x |")
    fem = [r for r in rows if r["scene"].startswith("FEM")]
    if fem:
        f = fem[0]
        floor = (f["receiving_ms"] + f["handling_ms"] + f["sending_ms"]) / f["daemon_ms"]
        lines += ["", f"Target (issue 10): the session step on the ~66k-node FEM scene at least 20x faster than the "
                      f"full-scene call; measured {f['speedup']:.0f}x ({f['full_ms']:.0f} ms against "
                      f"{f['session_ms']:.1f} ms). Most of the full call is Python encoding the scene as JSON.",
                  "",
                  f"Target (issue 27 §3): session / daemon at most 1.3 on the FEM scene; measured "
                  f"{f['session_over_daemon']:.2f} ({f['pool_over_daemon']:.2f} on urllib3's pool in the same "
                  f"rounds), **not reached**. The FEM scene sends every mesh node ({f['nodes']:,}) though only "
                  f"{f['surface_nodes']:,} are on a surface: {f['session_request_mb']:.1f} MB each way. The daemon alone spends "
                  f"{f['receiving_ms']:.2f} ms receiving that body and {f['sending_ms']:.2f} ms sending its answer "
                  f"outside its own {f['daemon_ms']:.2f} ms (floor {floor:.2f}): copying "
                  f"{2 * f['session_request_mb']:.1f} MB through loopback "
                  "costs more than the 0.3 of the daemon's time the target leaves to everything outside it."]
        ex = [r for r in rows if r["exchange"] == "surface"]
        if ex:
            e = ex[0]
            lines += ["", f"The FEM scene with a surface exchange (`client.session(scene, exchange=\"surface\")`: "
                          f"a binary step with `?nodes=surface` carries the {e['surface_nodes']:,} surface nodes' "
                          f"positions and forces alone, {e['session_request_mb'] * 1e3:.0f} kB each way; "
                          "docs/sessions.md) answers the same forces bit for bit (checked in the run) in "
                          f"{e['session_ms']:.2f} ms against {f['session_ms']:.2f} ms, "
                          f"{f['session_ms'] / e['session_ms']:.1f} times faster in wall time; the daemon's own "
                          f"time {e['daemon_ms']:.2f} ms against {f['daemon_ms']:.2f} ms (the loops' nodes alone "
                          "read, checked and taken: `nts_evaluate_surface_positions`). Its ratio to the daemon's own "
                          f"time, {e['session_over_daemon']:.2f}, stays above 1.3 for the reason below: the fixed cost "
                          "of an exchange."]
        surf = [r for r in rows if r["scene"].startswith("FEM's surfaces")]
        if surf:
            g = surf[0]
            lines += ["", f"The last row is the same four disks' surfaces alone ({g['nodes']:,} nodes, the outer "
                          f"rings as loops): what a step would cost if it carried the surface nodes only. The daemon "
                          f"takes {g['daemon_ms']:.2f} ms there against {f['daemon_ms']:.2f} ms with every mesh node: "
                          f"most of its own time on the FEM scene is reading, checking and writing the interior "
                          f"nodes' 1 MB each way, not contact. A step of {g['session_ms']:.2f} ms against "
                          f"{f['session_ms']:.2f} ms, but a ratio of {g['session_over_daemon']:.2f}: the fixed cost of "
                          "an exchange on this machine (two wake-ups across its cores, the client's Python) weighs "
                          "more against a smaller daemon time. A ratio to the daemon's own time rewards a slower "
                          "daemon; the wall time of the step is what a solver pays."]
    lines.append("")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="4,12,40", help="disks per side of the packings (x64 nodes each)")
    ap.add_argument("--fem-nodes", type=int, default=66000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=str(REPO / "docs" / "benchmarks.md"))
    a = ap.parse_args()
    proc, port = start_daemon()
    url = f"http://127.0.0.1:{port}"
    rows = []
    try:
        with ntscontact.Client(url, timeout=600) as client:
            for side in map(int, a.sizes.split(",")):
                rows.append(measure(client, f"packing {side}x{side} disks", packing_scene(side), a.repeats))
                print(json.dumps(rows[-1]), flush=True)
            rows.append(measure(client, "FEM: 4 triangle-mesh disks", fem_scene(a.fem_nodes), a.repeats))
            print(json.dumps(rows[-1]), flush=True)
            rows.append(measure(client, "FEM, surface exchange (`?nodes=surface`)", fem_scene(a.fem_nodes), a.repeats,
                                exchange="surface"))
            print(json.dumps(rows[-1]), flush=True)
            rows.append(measure(client, "FEM's surfaces alone: the 4 outer rings", fem_surface_scene(a.fem_nodes),
                                a.repeats))
            print(json.dumps(rows[-1]), flush=True)
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    write_results(rows, "sessions_python.csv", a.out, SECTION, markdown(rows, a.repeats))


if __name__ == "__main__":
    main()
