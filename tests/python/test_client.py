"""The Python client `ntscontact` against the real daemon (the `daemon` fixture of
conftest.py) and, for the failure modes a healthy daemon does not produce on
demand (500, 503, a server that never answers), against small local stand-ins on
127.0.0.1."""
import json
import math
import socket
import subprocess
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest

ntscontact = pytest.importorskip("ntscontact")
from ntscontact import (  # noqa: E402
    Client,
    InvalidScene,
    NtsError,
    PayloadTooLarge,
    RequestRejected,
    Scene,
    ServerError,
    ServiceUnavailable,
    Timeout,
)

EXAMPLES = sorted((__import__("pathlib").Path(__file__).resolve().parents[2] / "examples").glob("*.json"))


def _without_elapsed(doc):
    doc = json.loads(json.dumps(doc))
    doc.get("summary", {}).pop("elapsed_ms", None)
    return doc


def _cli(paths, *args, input=None):
    proc = subprocess.run([str(paths.cli), *map(str, args)], input=input, capture_output=True, timeout=120)
    return proc


@pytest.fixture(scope="module")
def client(daemon):
    with Client(daemon.base, timeout=30) as c:
        yield c


def disk(cx, cy, r=1.0, n=32, phase=0.0):
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1)


def two_disks_scene(**opts):
    s = Scene(penalty=opts.pop("penalty", 100.0), alpha=opts.pop("alpha", 0.2),
              search_radius=opts.pop("search_radius", 0.1), **opts)
    s.add_body(disk(0.0, 0.0), id="left")
    s.add_body(disk(1.96, 0.01, phase=0.05), id=7)
    return s


# ------------------------------------------------------------------ scenes


def test_examples_exist():
    assert len(EXAMPLES) >= 4, EXAMPLES


def test_a_scene_json_cannot_write_is_named_where_it_is():
    """Scene.to_json of options JSON cannot hold: InvalidScene at its
    pointer, as dump_document says for a dict (it was json's bare
    ValueError or TypeError); numpy's scalars written as the numbers they
    hold."""
    import types

    held: dict = {"a": []}
    held["a"].append(held)
    for extra, code, pointer in (({"x": math.nan}, "non_finite", "/options/x"),
                                 ({(1,): 2}, "invalid_type", "/options"),
                                 ({"x": object()}, "invalid_type", "/options/x"),
                                 ({math.nan: 1}, "non_finite", "/options"),
                                 # as json.dumps meets them: each key, then its value
                                 ({"a": math.inf, (1,): 2}, "non_finite", "/options/a"),
                                 ({"m": types.MappingProxyType({"x": 1})}, "invalid_type", "/options/m"),
                                 # keys spelled as JSON writes them
                                 ({True: {"x/~": [0, math.nan]}}, "non_finite", "/options/true/x~1~0/1"),
                                 ({"h": held}, "invalid_type", "/options/h/a/0")):  # (json: "Circular reference")
        with pytest.raises(InvalidScene) as info:
            Scene(penalty=1.0, extra_options=extra).to_json()
        assert (info.value.code, info.value.pointer) == (code, pointer), str(info.value)
    assert json.loads(Scene(penalty=1.0, extra_options={"x": np.int64(3)}).to_json())["options"]["x"] == 3


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_round_trips_through_scene(path):
    doc = json.loads(path.read_text())
    scene = Scene.load(path)
    assert scene.to_dict() == doc
    again = Scene.from_json(scene.to_json())
    assert again.to_dict() == doc
    # numpy in: every body's nodes are (n, 2) float64, bitwise the file's numbers
    for body, raw in zip(scene, doc["bodies"]):
        assert body.nodes.dtype == np.float64 and body.nodes.shape == (len(raw["nodes"]), 2)
        assert np.array_equal(body.nodes, np.array(raw["nodes"], dtype=np.float64))
        if "triangles" in raw:
            assert body.triangles.shape == (len(raw["triangles"]), 3)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_result_equals_cli(client, paths, path):
    proc = _cli(paths, path)
    assert proc.returncode == 0, proc.stderr
    cli = json.loads(proc.stdout)
    result = client.contact(Scene.load(path))
    assert _without_elapsed(result.raw) == _without_elapsed(cli)
    # numpy out: forces per body id, aligned with the nodes sent
    scene = Scene.load(path)
    if "forces" in (scene.outputs or ["forces"]):
        assert list(result.forces) == scene.body_ids
        for body in scene:
            f = result.forces[body.id]
            assert f.dtype == np.float64 and f.shape == body.nodes.shape
            assert np.array_equal(f, np.array(next(b["forces"] for b in cli["bodies"] if b["id"] == body.id)))
    assert result.energy == cli["summary"]["energy"]
    assert result.virial.shape == (2, 2) and result.virial[0, 1] == result.virial[1, 0]
    assert result.summary.contacts == cli["summary"]["contacts"]


def test_same_scene_as_dict_text_and_scene(client):
    scene = two_disks_scene()
    a = client.contact(scene)
    b = client.contact(scene.to_dict())
    c = client.contact(scene.to_json())
    assert _without_elapsed(a.raw) == _without_elapsed(b.raw) == _without_elapsed(c.raw)


def test_numpy_results_are_consistent(client):
    scene = two_disks_scene(outputs=["forces", "energy", "virial", "contacts", "gaps"])
    res = client.contact(scene)
    eps = scene.penalty
    assert res.summary.contacts == len(res.contacts) > 0
    assert set(res.forces) == {"left", 7}
    total = res.force_array()
    assert total.shape == (64, 2)
    assert np.allclose(total.sum(axis=0), 0.0, atol=1e-12 * np.abs(total).max())
    # energy = 1/2 eps sum g^2 over active contacts; virial = sum of the contacts' virials
    gaps = np.array([c.gap for c in res.contacts])
    assert np.all(gaps < 0)
    assert res.energy == pytest.approx(0.5 * eps * np.sum(gaps ** 2), rel=1e-12)
    assert np.allclose(res.virial, sum(c.virial_tensor for c in res.contacts), rtol=1e-12, atol=1e-15)
    cols = res.contact_arrays()
    assert cols["force"].shape == (len(res.contacts), 2)
    for c in res.contacts:
        # slave force -eps g n, master weights sum to one
        assert np.allclose(c.force, -eps * c.gap * np.array(c.normal), rtol=1e-12, atol=1e-14)
        assert math.isclose(sum(c.weights), 1.0, rel_tol=1e-12)
        assert c.kind in ("segment", "corner", "vertex")
        assert c.master_body != c.slave_body
    # every active contact is among the gaps, and the gaps hold inactive ones too
    active = {(g.slave_body, g.slave_node, g.master_body) for g in res.gaps if g.active}
    assert active == {(c.slave_body, c.slave_node, c.master_body) for c in res.contacts}
    assert any(not g.active for g in res.gaps)


def test_outputs_override(client):
    scene = two_disks_scene(outputs=["forces", "energy", "virial", "contacts"])
    only_forces = client.contact(scene, outputs=["forces"])
    assert only_forces.contacts == [] and set(only_forces.forces) == {"left", 7}
    only_contacts = client.contact(scene, outputs="contacts")
    assert only_contacts.forces == {} and len(only_contacts.contacts) == only_contacts.summary.contacts > 0
    assert scene.outputs == ["forces", "energy", "virial", "contacts"]  # the scene itself is untouched
    with pytest.raises(InvalidScene):
        client.contact(scene, outputs=["forces", "torques"])


def test_triangle_body_and_set_nodes(client):
    """A body given by triangles: forces for every node, interior ones zero; moving
    a body with set_nodes changes the answer and nothing else."""
    ring = disk(0.0, 0.0, n=12)
    nodes = np.vstack([[0.0, 0.0], ring])
    tris = np.array([[0, 1 + i, 1 + (i + 1) % 12] for i in range(12)])
    s = Scene(penalty=50.0, alpha=0.1, search_radius=0.2)
    s.add_body(nodes, triangles=tris, id="fan")
    s.add_body(disk(1.95, 0.0, n=12), id="loop")
    res = client.contact(s)
    assert res.forces["fan"].shape == (13, 2)
    assert np.all(res.forces["fan"][0] == 0.0)
    assert res.summary.contacts > 0
    s.set_nodes("loop", disk(2.5, 0.0, n=12))
    apart = client.contact(s)
    assert apart.summary.contacts == 0 and apart.energy == 0.0
    assert not np.any(apart.force_array())


def test_validate_health_schema(client, daemon, paths):
    report = client.validate(two_disks_scene())
    assert report["valid"] is True
    health = client.health()
    assert health["status"] == "ok" and health["version"] == ntscontact.__version__
    for name in ("scene", "result", "error"):
        assert client.schema(name) == json.loads((paths.schemas / f"{name}.schema.json").read_text())
    assert "openapi" in client.openapi()


# ------------------------------------------------------------------ errors


def test_client_side_checks_name_the_node():
    s = Scene(penalty=1.0)
    s.add_body(disk(0, 0, n=8), id="ok")
    bad = disk(3, 0, n=8)
    bad[5, 1] = np.nan
    with pytest.raises(InvalidScene) as ei:
        s.add_body(bad, id="cell-7")
    e = ei.value
    assert e.code == "non_finite" and e.pointer == "/bodies/1/nodes/5"
    assert "cell-7" in str(e) and "node 5" in str(e)
    assert len(s) == 1
    for nodes, code in (([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "invalid_type"), (np.zeros((0, 2)), "no_nodes"),
                        ([[0, 0], [1, 0]], "loop_too_short")):
        with pytest.raises(InvalidScene) as ei:
            s.add_body(nodes)
        assert ei.value.code == code
    with pytest.raises(InvalidScene, match="out of range"):
        s.add_body(disk(0, 3, n=8), loops=[[0, 1, 8]])
    with pytest.raises(InvalidScene, match="duplicate"):
        s.add_body(disk(0, 3, n=8), id="ok")
    with pytest.raises(InvalidScene) as ei:
        s.add_body(np.array([[0, 0], [1, 0], [np.inf, 1]]), id=3)
    assert ei.value.pointer == "/bodies/1/nodes/2" and isinstance(ei.value, ValueError)
    no_penalty = Scene()
    no_penalty.add_body(disk(0, 0, n=8))
    with pytest.raises(InvalidScene, match="penalty"):  # checked before anything is sent
        Client("http://127.0.0.1:9", retries=0).contact(no_penalty)


@pytest.mark.parametrize("np_id", [np.int64(7), np.int32(7), np.uint8(7)])
def test_numpy_integer_ids_are_the_ints_they_are(client, np_id):
    """A numpy integer is taken wherever an int is: as a body id (it was
    refused as "got int64"), stored as the int, and to find the body again
    (Scene.body, a session's positions by body, a binary answer's forces);
    a numpy bool is refused as a bool is."""
    scene = Scene(penalty=100.0, alpha=0.2, search_radius=0.1)
    scene.add_body(disk(0.0, 0.0), id="left")
    got = scene.add_body(disk(1.96, 0.01, phase=0.05), id=np_id)
    assert type(got) is int and got == 7 and scene.body_ids == ["left", 7]
    assert scene.body(np_id) is scene.body(7) and scene.index_of(np_id) == 1
    want = client.contact(two_disks_scene(), outputs=["forces"])
    assert np.array_equal(client.contact(scene, outputs=["forces"]).force_array(), want.force_array())
    with client.session(scene) as s:
        moved = disk(1.95, 0.01, phase=0.05)
        r = s.contact({np_id: moved}, outputs=["forces"])
        assert np.array_equal(s.positions()[32:], moved) and np.array_equal(r.forces[np_id], r.forces[7])
    with pytest.raises(InvalidScene) as ei:
        scene.add_body(disk(5.0, 0.0), id=np.bool_(True))
    assert ei.value.code == "invalid_type" and ei.value.pointer == "/bodies/2/id"


@pytest.mark.parametrize("flag", [True, np.bool_(False)])
@pytest.mark.parametrize("where", ["penalty", "alpha", "search_radius", "surface_extension", "periodic",
                                   "body alpha", "skin", "step alpha"])
def test_a_boolean_is_not_a_number(client, flag, where):
    """A boolean where a number goes (float() reads it as 0 or 1, and
    Scene(penalty=True) evaluated with a penalty of 1) is refused as the
    service refuses it in the same document: invalid_type, its pointer and
    its words."""
    doc = two_disks_scene().to_dict()
    kw = {"penalty": 100.0, "alpha": 0.2, "search_radius": 0.1}
    if where in ("penalty", "alpha", "search_radius", "surface_extension"):
        doc["options"][where] = bool(flag)
        kw[where] = flag
    elif where == "periodic":
        doc["options"]["periodic"] = {"lx": bool(flag), "ly": 10.0}
        kw["periodic"] = (flag, 10.0)
    elif where == "body alpha":
        doc["bodies"][1]["alpha"] = bool(flag)
    elif where == "skin":
        doc["session"] = {"skin": bool(flag)}
    if where == "step alpha":
        want = ("invalid_type", "/options/alpha")  # (the service reads the query's alpha=true as not a number)
    else:
        with pytest.raises(InvalidScene) as service:
            client.session(doc) if where == "skin" else client.contact(doc)
        want = (service.value.code, service.value.pointer)
        assert service.value.message == "expected a number, got a boolean"
    with pytest.raises(InvalidScene) as ours:
        scene = Scene(**kw)
        scene.add_body(disk(0.0, 0.0), id="left")
        scene.add_body(disk(1.96, 0.01, phase=0.05), id=7, alpha=flag if where == "body alpha" else None)
        with client.session(scene, skin=flag if where == "skin" else None) as s:
            s.contact(alpha=flag if where == "step alpha" else None)
    assert (ours.value.code, ours.value.pointer) == want
    assert ours.value.message == "expected a number, got a boolean"
    scene = Scene(penalty=100.0)
    scene.penalty = flag  # set after the scene is made: refused when it is sent
    with pytest.raises(InvalidScene) as ours:
        scene.to_dict()
    assert (ours.value.code, ours.value.pointer) == ("invalid_type", "/options/penalty")


def test_numpy_numbers_are_friction_coefficients():
    """The friction coefficients take numpy numbers as they take ints and
    floats (np.float32(0.3) and np.int64(1) were "must be a number")."""
    scene = Scene(penalty=100.0, friction=np.int64(1))
    scene.add_body(disk(0.0, 0.0), id="left", friction=np.float32(0.5))
    assert scene.to_dict()["options"]["friction"] == {"coefficient": 1.0}
    assert scene.body("left").friction == float(np.float32(0.5))
    for bad in (True, np.bool_(True)):
        with pytest.raises(InvalidScene):
            Scene(penalty=100.0, friction=bad)
        with pytest.raises(InvalidScene):
            scene.add_body(disk(3.0, 0.0), friction=bad)


SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


@pytest.mark.parametrize("field, value, given", [
    ("triangles", np.array([[0, 1, 2], [0, 2, 2 ** 63]], dtype=np.uint64), "9223372036854775808"),
    ("triangles", [[0, 1, 2], [0, 2, 1e300]], "1e+300"),
    ("triangles", [[0, 1, 2], [0, -1e300, 3]], "-1e+300"),
    ("triangles", [[0, 1, 2], [0, 2, 2.5]], "2.5"),
    ("loops", [[0, 1, 2, 2 ** 64 - 1]], "18446744073709551615"),
    ("loops", [[0.0, 1.0, 2.0, 3.5]], "3.5"),
    ("loops", [[0, 1, 2, 2 ** 64]], "18446744073709551616"),  # (numpy keeps it as an object)
    ("loops", [[0, 1, 2, True]], "boolean"),  # (numpy reads it as 1)
    ("triangles", [[0, 1, 2], [0, np.bool_(False), 3]], "boolean"),
])
def test_node_indices_beyond_int64_or_not_integers_are_refused_as_given(client, field, value, given):
    """Node indices are checked before the cast to int64 (a uint64 2**63 or a
    float 1e300 wrapped to -9223372036854775808, which the error then
    named): add_body refuses them with the service's code and pointer for
    the same document, naming the value as given."""
    as_json = value.tolist() if isinstance(value, np.ndarray) else json.loads(json.dumps(value, default=bool))
    doc = {"options": {"penalty": 100.0}, "bodies": [{"id": 0, "nodes": SQUARE, field: as_json},
                                                    {"id": 1, "nodes": (np.array(SQUARE) + [2, 0]).tolist()}]}
    with pytest.raises(InvalidScene) as service:
        client.contact(json.dumps(doc))
    with pytest.raises(InvalidScene) as ours:
        Scene(penalty=100.0).add_body(SQUARE, **{field: value})
    assert (ours.value.code, ours.value.pointer) == (service.value.code, service.value.pointer)
    assert given in ours.value.message and "-9223372036854775808" not in str(ours.value)


@pytest.mark.parametrize("mutate, code, pointer", [
    (lambda d: d["bodies"][1]["nodes"].__setitem__(3, list(d["bodies"][1]["nodes"][2])),
     "degenerate_segment", "/bodies/1"),
    (lambda d: d["bodies"][0].__setitem__("loops", [[0, 1, 999]]), "index_out_of_range", "/bodies/0/loops/0"),
    (lambda d: d["options"].pop("penalty"), "missing_field", "/options"),
    (lambda d: d["options"].__setitem__("alpha", 0.9), "invalid_option", "/options/alpha"),
    (lambda d: d["bodies"][1].__setitem__("id", "left"), "duplicate_id", "/bodies/1"),
])
def test_service_errors_become_invalid_scene(client, mutate, code, pointer):
    doc = two_disks_scene().to_dict()
    mutate(doc)
    with pytest.raises(InvalidScene) as ei:
        client.contact(doc)
    e = ei.value
    assert e.status == 400 and e.code == code and e.pointer.startswith(pointer), (e.code, e.pointer, str(e))
    assert e.message


def test_service_error_message_names_body_and_node(client):
    doc = two_disks_scene().to_dict()
    doc["bodies"][1]["nodes"][4] = list(doc["bodies"][1]["nodes"][3])
    with pytest.raises(InvalidScene) as ei:
        client.contact(doc)
    text = str(ei.value)
    assert "body 7 (index 1)" in text and "node" in text, text
    # raw JSON text is sent as it is: the service's own checks answer
    raw = '{"version":1,"options":{"penalty":1},"bodies":[{"id":"x","nodes":[[0,0],[1,0],[1,1e999]]}]}'
    with pytest.raises(InvalidScene) as ei:
        client.contact(raw)
    assert ei.value.code in ("non_finite", "invalid_value") and ei.value.pointer.startswith("/bodies/0/nodes")
    with pytest.raises(InvalidScene) as ei:
        client.validate("{not json")
    assert ei.value.code == "invalid_json"


def test_payload_too_large(daemon_factory):
    d = daemon_factory("--max-bytes", "4k", "--quiet")
    s = Scene(penalty=1.0)
    s.add_body(disk(0, 0, n=400))
    with Client(d.base, timeout=30) as c:
        with pytest.raises(PayloadTooLarge) as ei:
            c.contact(s)
        assert ei.value.status == 413 and ei.value.code == "payload_too_large"
        assert c.health()["status"] == "ok"


def test_unknown_path_is_rejected(client):
    with pytest.raises(RequestRejected) as ei:
        client.schema("nope")
    assert ei.value.status == 404 and isinstance(ei.value, NtsError)


class _Stub:
    """A local HTTP server answering every request with (status, body); it records
    the request headers."""

    def __init__(self, status=200, body=b'{"status": "ok"}', content_type="application/json"):
        stub = self
        self.headers = []

        class Handler(BaseHTTPRequestHandler):
            def _answer(self):
                stub.headers.append(dict(self.headers))
                n = int(self.headers.get("Content-Length") or 0)
                if n:
                    self.rfile.read(n)
                self.send_response(status)
                self.send_header("Content-Type", content_type)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            do_GET = do_POST = _answer

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.base = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


@pytest.mark.parametrize("status, exc, code", [
    (503, ServiceUnavailable, "overloaded"),
    (500, ServerError, "internal_error"),
    (413, PayloadTooLarge, "payload_too_large"),
    (415, RequestRejected, "unsupported_media_type"),
])
def test_status_maps_to_exception(status, exc, code):
    body = json.dumps({"error": {"code": code, "message": "stand-in", "pointer": ""}}).encode()
    stub = _Stub(status, body)
    try:
        with Client(stub.base, timeout=10) as c:
            with pytest.raises(exc) as ei:
                c.contact(two_disks_scene())
        assert ei.value.code == code and ei.value.status == status
        assert len(stub.headers) == 1  # a status is never retried
    finally:
        stub.close()


def test_non_json_answer_is_a_server_error():
    stub = _Stub(200, b"<html>hello</html>", content_type="text/html")
    try:
        with Client(stub.base, timeout=10) as c, pytest.raises(ServerError):
            c.health()
    finally:
        stub.close()


def test_user_agent_and_content_type():
    stub = _Stub()
    try:
        with Client(stub.base, timeout=10) as c:
            c.health()
            with pytest.raises(ServerError):  # the stand-in's answer is no result
                c.contact(two_disks_scene())
        get, post = stub.headers
        assert get["User-Agent"] == f"ntscontact-python/{ntscontact.__version__}"
        assert post["User-Agent"] == get["User-Agent"]
        assert post["Content-Type"] == "application/json"
    finally:
        stub.close()


# ------------------------------------------------------------------ timeouts and retries


def _pending_connections(listener):
    listener.setblocking(False)
    n = 0
    while True:
        try:
            conn, _ = listener.accept()
        except BlockingIOError:
            return n
        conn.close()
        n += 1


def test_timeout_honoured_and_not_retried():
    """A socket that accepts (the kernel's backlog) and never answers: the call ends
    with Timeout, and the request was sent once (read failures are not retried)."""
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(16)
    base = f"http://127.0.0.1:{listener.getsockname()[1]}"
    try:
        with Client(base, timeout=0.3, retries=3) as c:
            with pytest.raises(Timeout) as ei:
                c.contact(two_disks_scene())
            assert isinstance(ei.value, TimeoutError) and isinstance(ei.value, NtsError)
            assert _pending_connections(listener) == 1
            with pytest.raises(Timeout):  # a per-call timeout overrides the client's
                c.health(timeout=(1.0, 0.2))
            assert _pending_connections(listener) == 1
    finally:
        listener.close()


def test_connection_refused_is_service_unavailable():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    with Client(f"http://127.0.0.1:{port}", timeout=2, retries=1, backoff=0.0) as c:
        with pytest.raises(ServiceUnavailable) as ei:
            c.health()
    assert ei.value.status is None and ei.value.code == "unreachable"


def test_connection_failures_are_retried():
    """Refused connections are retried (with backoff) until the service is up."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    ready = threading.Event()
    holder = {}

    def late_server():
        ready.wait(10)
        import http.server

        class H(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                body = b'{"status": "ok", "late": true}'
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *a):
                pass

        srv = ThreadingHTTPServer(("127.0.0.1", port), H)
        holder["srv"] = srv
        srv.serve_forever()

    t = threading.Thread(target=late_server, daemon=True)
    t.start()
    with Client(f"http://127.0.0.1:{port}", timeout=5, retries=8, backoff=0.05) as c:
        ready.set()  # the server binds while the client is retrying refused connections
        assert c.health() == {"status": "ok", "late": True}
    holder["srv"].shutdown()
    holder["srv"].server_close()


def test_module_command_line(daemon, paths, tmp_path):
    """`python -m ntscontact contact SCENE --url` answers as the C CLI does."""
    import sys

    path = paths.examples / "two_disks.json"
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "contact", str(path), "--url", daemon.base],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    cli = _cli(paths, path)
    assert _without_elapsed(json.loads(proc.stdout)) == _without_elapsed(json.loads(cli.stdout))
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "health", "--url", daemon.base],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and json.loads(proc.stdout)["status"] == "ok"
    bad = tmp_path / "bad.json"
    bad.write_text('{"version": 1, "options": {"penalty": 1}, "bodies": [{"id": 1, "nodes": [[0, 0], [1, 0]]}]}')
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "contact", str(bad), "--url", daemon.base],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 3 and "loop_too_short" in proc.stderr
