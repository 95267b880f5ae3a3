"""Friction with history (docs/model.md §14) through every door: the scene's
"friction" option and a body's own, the result's friction fields and its
"history", a stateless request that goes on from a history, sessions that keep
it (commit, ?commit=false, JSON and binary steps, NTS-Dissipation headers),
the CLI's --history-in / --history-out / --frames, the VTK fields, the schemas,
and every bad input with its code and JSON pointer from the CLI (exit 3) and
the daemon (400)."""
import copy
import json
import subprocess

import jsonschema
import numpy as np
import pytest
import requests

from conftest import CLI

ntscontact = pytest.importorskip("ntscontact")
meshio = pytest.importorskip("meshio")

MU = 0.3


def block_scene(mu=MU, outputs=("forces", "contacts"), **extra_options):
    """A block pressed 0.01 into a flat with smoothed corners: the flat's top has
    nodes at x = -1, 0, 1 and the block's bottom at -0.5, 0, 0.5 (non-matching)."""
    options = {"penalty": 1000.0, "alpha": 0.2, "outputs": list(outputs)}
    if mu is not None:
        options["friction"] = {"coefficient": mu}
    options.update(extra_options)
    return {"options": options, "bodies": [
        {"id": "flat", "nodes": [[-2, -1], [2, -1], [2, 0], [1, 0], [0, 0], [-1, 0], [-2, 0]]},
        {"id": 7, "nodes": [[-0.5, -0.01], [0, -0.01], [0.5, -0.01], [0.5, 1], [-0.5, 1]]}]}


def path_positions(scene, steps=8):
    """The block dragged right (1e-3 per step, sticking then slipping) and
    pushed down and back at the end: every state, and a contact that opens."""
    x0 = np.array([p for b in scene["bodies"] for p in b["nodes"]], dtype=float)
    out = []
    for k in range(steps):
        x = x0.copy()
        dx = 1e-3 * (k + 1) if k < steps - 2 else 1e-3 * (steps - 2) - 4e-3 * (k - steps + 3)
        x[7:, 0] += dx
        x[7:, 1] += -0.002 * (k % 3) + (0.02 if k == steps - 1 else 0.0)  # the last step lifts one side off
        if k == steps - 1:
            x[7:, 1] += np.array([0.0, 0.0, -0.025, 0.0, 0.0])[: len(x) - 7]
        out.append(x)
    return out


def with_positions(scene, x):
    doc = copy.deepcopy(scene)
    doc["bodies"][0]["nodes"] = x[:7].tolist()
    doc["bodies"][1]["nodes"] = x[7:].tolist()
    return doc


JSON = {"Content-Type": "application/json"}


def post(daemon, doc):
    r = requests.post(daemon.base + "/v1/contact", data=json.dumps(doc), headers=JSON, timeout=30)
    return r.status_code, r.json()


def without_elapsed(doc):
    doc = copy.deepcopy(doc)
    doc["summary"].pop("elapsed_ms", None)
    return doc


def run_cli(doc, *flags, tmp_path=None, check=True):
    r = subprocess.run([str(CLI), *flags, "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    if check:
        assert r.returncode == 0, r.stderr
    return r


# ------------------------------------------------------------ answers


def test_friction_fields_only_with_friction(daemon, schemas):
    """Friction on: the summary's dissipation, sticking and slipping, the virial's
    yx, each contact's tangential force, state, slip and anchor, the history; a
    coefficient 0 is the answer of a scene without friction, byte for byte."""
    status, on = post(daemon, block_scene())
    assert status == 200
    jsonschema.validate(on, schemas["result"], cls=jsonschema.Draft202012Validator)
    assert on["summary"]["sticking"] == on["summary"]["contacts"] > 0 and on["summary"]["slipping"] == 0
    assert on["summary"]["dissipation"] == 0.0 and "yx" in on["summary"]["virial"]
    assert len(on["history"]) == len(on["contacts"])
    for c, h in zip(on["contacts"], on["history"]):
        assert c["state"] == "stick" and c["tangential_force"] == [0.0, 0.0] and c["slip"] == 0.0
        assert {k: h[k] for k in ("kind", "nodes", "param")} == c["anchor"]
        assert h["slave"] == c["slave"] and h["master"] == c["master"]["body"]
    off = run_cli(block_scene(mu=None)).stdout
    zero = run_cli(block_scene(mu=0.0)).stdout
    assert json.dumps(without_elapsed(json.loads(off))) == json.dumps(without_elapsed(json.loads(zero)))
    doc = json.loads(off)
    assert "history" not in doc and "dissipation" not in doc["summary"] and "yx" not in doc["summary"]["virial"]
    assert all("state" not in c for c in doc["contacts"])


def stateless_chain(daemon, scene, xs):
    """Each position evaluated alone, carrying the previous answer's history."""
    out, history = [], None
    for x in xs:
        doc = with_positions(scene, x)
        if history is not None:
            doc["history"] = history
        status, res = post(daemon, doc)
        assert status == 200, res
        out.append(res)
        history = res["history"]
    return out


def test_stateless_history_chain_equals_a_session(daemon, schemas):
    """A session committing every step answers what the stateless requests
    carrying the previous history answer, bit for bit (elapsed_ms aside); the
    drag goes from stick to slip, dissipating mu |f_N| |slip|."""
    scene = block_scene()
    xs = path_positions(scene)
    chain = stateless_chain(daemon, scene, xs)
    assert any(r["summary"]["slipping"] > 0 for r in chain) and any(r["summary"]["dissipation"] > 0 for r in chain)
    assert all(r["summary"]["dissipation"] >= 0 for r in chain)
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(scene), headers=JSON, timeout=30).json()["id"]
    try:
        for x, want in zip(xs, chain):
            r = requests.post(f"{daemon.base}/v1/scenes/{sid}/contact", data=json.dumps({"positions": x.tolist()}),
                              headers=JSON, timeout=30)
            assert r.status_code == 200
            got = r.json()
            jsonschema.validate(got, schemas["result"], cls=jsonschema.Draft202012Validator)
            assert without_elapsed(got) == without_elapsed(want)
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)
    for r in chain:  # slip: the tangential force is mu |f_N| (docs/model.md (25))
        for c in r["contacts"]:
            fn = np.dot(c["force"], c["normal"])
            ft = np.hypot(*c["tangential_force"])
            if c["state"] == "slip":
                assert ft == pytest.approx(MU * abs(fn), rel=1e-12)
            else:
                assert ft <= MU * abs(fn) * (1 + 1e-12)


def test_commit_false_leaves_the_history(daemon):
    """Trials with commit false (JSON field or query) answer from the same
    committed history whatever came before; committing one moves it on."""
    scene = block_scene()
    xs = path_positions(scene)
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(scene), headers=JSON, timeout=30).json()["id"]
    url = f"{daemon.base}/v1/scenes/{sid}/contact"
    try:
        step = lambda x, **kw: requests.post(url, data=json.dumps({"positions": x.tolist(), **kw}),  # noqa: E731
                                             headers=JSON, timeout=30).json()
        base = step(xs[1])                                   # committed
        a = step(xs[3], commit=False)
        step(xs[5], commit=False)                            # a trial elsewhere: forgotten
        b = requests.post(url, data=json.dumps({"positions": xs[3].tolist()}), params={"commit": "false"},
                          headers=JSON, timeout=30).json()
        assert without_elapsed(a) == without_elapsed(b)
        c = step(xs[3])                                      # now committed
        assert without_elapsed(c) == without_elapsed(a)
        d = step(xs[4])
        _, want = post(daemon, dict(with_positions(scene, xs[4]), history=c["history"]))
        assert without_elapsed(d) == without_elapsed(want)
        assert c["history"] == base["history"] and c["summary"]["slipping"] == 0  # stuck: the anchors stay
        _, fresh = post(daemon, with_positions(scene, xs[4]))  # no history: every contact new, no tangential force
        assert without_elapsed(d) != without_elapsed(fresh)  # the committed anchors pull
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)


def test_binary_steps_and_their_headers(daemon):
    """A binary step answers the JSON step's forces bit for bit, with the
    dissipation, sticking and slipping in headers and a four-value virial; the
    Python client reads them, and a session created with a history starts from it."""
    scene = block_scene(outputs=("forces",))
    xs = path_positions(scene)
    client = ntscontact.Client(daemon.base)
    json_answers = []
    with client.session(ntscontact.Scene.from_dict(scene)) as s:
        for x in xs:
            json_answers.append(s.step(x, outputs=["forces", "contacts"]))  # a JSON answer
    with client.session(ntscontact.Scene.from_dict(scene)) as s:
        for x, want in zip(xs, json_answers):
            got = s.step(x)  # forces only: the client takes the binary answer
            assert got.raw == {}
            assert np.array_equal(got.force_array(), want.force_array())
            assert got.summary.dissipation == want.summary.dissipation
            assert (got.summary.sticking, got.summary.slipping) == (want.summary.sticking, want.summary.slipping)
            assert np.array_equal(got.summary.virial, want.summary.virial) and got.summary.friction
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(scene), headers=JSON, timeout=30).json()["id"]
    try:
        r = requests.post(f"{daemon.base}/v1/scenes/{sid}/contact", data=xs[2].astype("<f8").tobytes(),
                          headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                          timeout=30)
        assert r.status_code == 200
        assert len(r.headers["NTS-Virial"].split(",")) == 4
        for h in ("NTS-Dissipation", "NTS-Sticking", "NTS-Slipping"):
            assert h in r.headers
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)
    off = block_scene(mu=None, outputs=("forces",))
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(off), headers=JSON, timeout=30).json()["id"]
    try:
        r = requests.post(f"{daemon.base}/v1/scenes/{sid}/contact", data=b"",
                          headers={"Accept": "application/octet-stream"}, timeout=30)
        assert len(r.headers["NTS-Virial"].split(",")) == 3 and "NTS-Dissipation" not in r.headers
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)
    # a session created with a history goes on from it: as the stateless request does
    assert json_answers[3].history == json_answers[3].raw["history"] and json_answers[3].contacts
    start = with_positions(scene, xs[3])
    _, first = post(daemon, start)
    created = dict(scene, history=first["history"])
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(created), headers=JSON, timeout=30).json()["id"]
    try:
        got = requests.post(f"{daemon.base}/v1/scenes/{sid}/contact",
                            data=json.dumps({"positions": xs[5].tolist()}), headers=JSON, timeout=30).json()
        _, want = post(daemon, dict(with_positions(scene, xs[5]), history=first["history"]))
        assert without_elapsed(got) == without_elapsed(want)
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)


def test_cli_history_files_and_frames(daemon, tmp_path):
    """--history-out then --history-in answers what the daemon answers with the
    history in the request; --frames commits every frame (each line is the
    session's JSON step) and --history-out after it is the session's history."""
    scene = block_scene()
    xs = path_positions(scene)
    chain = stateless_chain(daemon, scene, xs)
    h = tmp_path / "h.json"
    prev = None
    for x, want in zip(xs, chain):
        flags = ["--history-out", str(h)] + (["--history-in", str(prev)] if prev else [])
        got = json.loads(run_cli(with_positions(scene, x), *flags).stdout)
        assert without_elapsed(got) == without_elapsed(want)
        saved = json.loads(h.read_text())
        assert saved == {"history": want["history"]}
        prev = tmp_path / "prev.json"
        prev.write_text(h.read_text())
    # a whole previous result is a history document too
    (tmp_path / "result.json").write_text(json.dumps(chain[2]))
    got = json.loads(run_cli(with_positions(scene, xs[3]), "--history-in", str(tmp_path / "result.json")).stdout)
    assert without_elapsed(got) == without_elapsed(chain[3])
    frames = tmp_path / "frames.bin"
    frames.write_bytes(b"".join(x.astype("<f8").tobytes() for x in xs))
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    r = subprocess.run([str(CLI), "--frames", str(frames), "--history-out", str(h), str(tmp_path / "scene.json")],
                       capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = [json.loads(line) for line in r.stdout.decode().splitlines()]
    assert [without_elapsed(d) for d in lines] == [without_elapsed(d) for d in chain]
    key = lambda a: (str(a["slave"]["body"]), a["slave"]["node"], str(a["master"]))  # noqa: E731
    assert sorted(json.loads(h.read_text())["history"], key=key) == sorted(chain[-1]["history"], key=key)


def test_vtk_friction_fields_from_c_and_python(daemon, tmp_path):
    """The C tool's and the Python client's .vtu carry the same tangential
    forces, friction states, virial (with yx) and dissipation."""
    scene = block_scene()
    xs = path_positions(scene)
    chain = stateless_chain(daemon, scene, xs[:3])
    doc = dict(with_positions(scene, xs[3]), history=chain[-1]["history"])
    (tmp_path / "s.json").write_text(json.dumps(doc))
    r = subprocess.run([str(CLI), "--vtk", str(tmp_path / "c.vtu"), str(tmp_path / "s.json")], capture_output=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    client = ntscontact.Client(daemon.base)
    res = client.contact(ntscontact.Scene.from_dict(with_positions(scene, xs[3])), history=chain[-1]["history"])
    assert res.summary.slipping + res.summary.sticking == res.summary.contacts > 0
    res.to_vtk(tmp_path / "py.vtu")
    a, b = meshio.read(tmp_path / "py.vtu"), meshio.read(tmp_path / "c.vtu")
    for key in ("tangential_force", "friction_state", "contact_force"):
        assert np.array_equal(np.concatenate(a.cell_data[key]), np.concatenate(b.cell_data[key])), key
    states = np.concatenate(b.cell_data["friction_state"])
    assert set(states[states >= 0]) <= {1, 2} and (states >= 1).any()
    for key in ("virial", "dissipation"):
        assert np.array_equal(np.asarray(a.field_data[key]).ravel(), np.asarray(b.field_data[key]).ravel()), key
    assert np.asarray(b.field_data["virial"]).size == 4


# ------------------------------------------------------------ bad input

def _history_entry():
    return {"slave": {"body": 7, "node": 1}, "master": "flat", "kind": "segment", "nodes": [4, 5], "param": 0.5}


def _bad(mutate):
    doc = block_scene()
    doc["history"] = [_history_entry()]
    mutate(doc)
    return doc


BAD = [
    (lambda d: d["options"]["friction"].update(coefficient=-0.1), "invalid_option", "/options/friction/coefficient"),
    (lambda d: d["options"]["friction"].update(coefficient=10.5), "invalid_option", "/options/friction/coefficient"),
    (lambda d: d["options"]["friction"].update(coefficient="0.3"), "invalid_type", "/options/friction/coefficient"),
    (lambda d: d["options"].update(friction=0.3), "invalid_type", "/options/friction"),
    (lambda d: d["options"].update(friction={}), "missing_field", "/options/friction/coefficient"),
    (lambda d: d["options"]["friction"].update(mu=1), "unknown_field", "/options/friction/mu"),
    (lambda d: d["options"]["friction"].update(tangential_penalty=-1), "invalid_option",
     "/options/friction/tangential_penalty"),
    (lambda d: d["bodies"][1].update(friction=-0.5), "invalid_option", "/bodies/1/friction"),
    (lambda d: d["bodies"][1].update(friction=11), "invalid_option", "/bodies/1/friction"),
    (lambda d: d["bodies"][1].update(friction=None), "invalid_type", "/bodies/1/friction"),
    (lambda d: d.update(history={}), "invalid_type", "/history"),
    (lambda d: d["history"].append(3), "invalid_type", "/history/1"),
    (lambda d: d["history"][0].update(master="nobody"), "invalid_history", "/history/0/master"),
    (lambda d: d["history"][0]["slave"].update(body=8), "invalid_history", "/history/0/slave/body"),
    (lambda d: d["history"][0]["slave"].update(node=5), "index_out_of_range", "/history/0/slave/node"),
    (lambda d: d["history"][0]["slave"].update(node=1.5), "invalid_value", "/history/0/slave/node"),
    (lambda d: d["history"][0].pop("param"), "missing_field", "/history/0/param"),
    (lambda d: d["history"][0].update(kind="edge"), "invalid_value", "/history/0/kind"),
    (lambda d: d["history"][0].update(nodes=[4]), "invalid_history", "/history/0/nodes"),
    (lambda d: d["history"][0].update(nodes=[4, 9]), "index_out_of_range", "/history/0/nodes/1"),
    (lambda d: d["history"][0].update(nodes=[4, 6]), "invalid_history", "/history/0"),  # not a segment
    (lambda d: d["history"][0].update(master=7, nodes=[0, 1]), "invalid_history", "/history/0"),  # on itself
    (lambda d: d["history"][0].update(param=1e300), "invalid_history", "/history/0"),
    (lambda d: d["history"][0].update(extra=1), "unknown_field", "/history/0/extra"),
    (lambda d: d["history"].append(_history_entry()), "invalid_history", "/history/1"),  # the key twice
]


@pytest.mark.parametrize("mutate,code,pointer", BAD, ids=[f"{b[1]}:{b[2]}" for b in BAD])
def test_bad_friction_input_named_by_the_cli_and_the_daemon(daemon, schemas, mutate, code, pointer):
    doc = _bad(mutate)
    status, err = post(daemon, doc)
    assert status == 400, err
    jsonschema.validate(err, schemas["error"])
    assert (err["error"]["code"], err["error"]["pointer"]) == (code, pointer), err
    r = run_cli(doc, check=False)
    assert r.returncode == 3
    assert f"{code} at \"{pointer}\"" in r.stderr.decode()
    # a session refuses it at creation with the same answer
    r = requests.post(daemon.base + "/v1/scenes", data=json.dumps(doc), headers=JSON, timeout=30)
    assert r.status_code == 400 and r.json() == err


def test_the_good_history_entry_is_accepted(daemon):
    status, res = post(daemon, _bad(lambda d: None))
    assert status == 200 and res["summary"]["contacts"] > 0


@pytest.mark.parametrize("body,params,code,pointer", [
    ({"commit": "no"}, None, "invalid_type", "/commit"),
    ({"commit": True, "positions": None}, None, "invalid_type", "/positions"),
    ({}, {"commit": "maybe"}, "invalid_value", "/commit"),
    ({"comit": False}, None, "unknown_field", "/comit"),
])
def test_bad_commit(daemon, body, params, code, pointer):
    sid = requests.post(daemon.base + "/v1/scenes", data=json.dumps(block_scene()), headers=JSON, timeout=30).json()["id"]
    try:
        r = requests.post(f"{daemon.base}/v1/scenes/{sid}/contact", data=json.dumps(body), params=params, headers=JSON,
                          timeout=30)
        assert r.status_code == 400
        assert (r.json()["error"]["code"], r.json()["error"]["pointer"]) == (code, pointer)
    finally:
        requests.delete(f"{daemon.base}/v1/scenes/{sid}", timeout=30)


def test_history_in_errors(tmp_path):
    scene = block_scene()
    for text, code, pointer in [("[1, 2", "invalid_json", None), ("{}", "missing_field", "/history"),
                                (json.dumps({"history": [dict(_history_entry(), master="x")]}), "invalid_history",
                                 "/history/0/master")]:
        (tmp_path / "h.json").write_text(text)
        r = run_cli(scene, "--history-in", str(tmp_path / "h.json"), check=False)
        assert r.returncode == 3, r.stderr
        assert code in r.stderr.decode() and (pointer is None or f'"{pointer}"' in r.stderr.decode())
    r = run_cli(scene, "--history-in", str(tmp_path / "missing.json"), check=False)
    assert r.returncode == 2


# ------------------------------------------------------------ the Python client

@pytest.mark.parametrize("friction,body_friction", [
    (-0.1, None), (10.5, None), ("0.3", None), ({}, None), ({"coefficient": 0.3, "mu": 1}, None),
    ({"coefficient": 0.3, "tangential_penalty": -1.0}, None), (0.3, -0.5), (0.3, 11.0),
])
def test_the_client_refuses_what_the_service_refuses(daemon, friction, body_friction):
    """Scene(friction=...) and add_body(friction=...) raise InvalidScene with the
    code and pointer the service gives for the same document."""
    doc = block_scene()
    doc["options"]["friction"] = friction if isinstance(friction, dict) else {"coefficient": friction}
    if body_friction is not None:
        doc["bodies"][1]["friction"] = body_friction
    status, err = post(daemon, doc)
    assert status == 400
    with pytest.raises(ntscontact.InvalidScene) as exc:
        s = ntscontact.Scene(penalty=1000.0, friction=friction)
        s.add_body(doc["bodies"][0]["nodes"], id="flat")
        s.add_body(doc["bodies"][1]["nodes"], id=7, friction=body_friction)
    assert (exc.value.code, exc.value.pointer) == (err["error"]["code"], err["error"]["pointer"])


@pytest.mark.parametrize("history", ["garbage", {"a": 1}, [1, 2], [{"slave": 0}, None], ({"a": 1},)])
def test_a_history_not_so_is_refused_as_the_service_refuses_it(daemon, history):
    """Client.contact(scene, history=...) of a wrong type: InvalidScene with
    the code, pointer and words the service gives for the same document (it
    was a ValueError or TypeError from dict()). Anchors that are mappings
    are the service's to read."""
    scene = block_scene()
    status, err = post(daemon, dict(scene, history=list(history) if isinstance(history, tuple) else history))
    assert status == 400
    with ntscontact.Client(daemon.base) as client, pytest.raises(ntscontact.InvalidScene) as exc:
        client.contact(scene, history=history)
    assert (exc.value.code, exc.value.pointer, exc.value.message) == \
        (err["error"]["code"], err["error"]["pointer"], err["error"]["message"])


def test_a_history_of_numpy_values_is_the_history_of_their_numbers(daemon):
    """Anchors whose nodes are a numpy array and whose parameter is a numpy
    float go as the lists and numbers they hold (json's bare TypeError
    before); a NaN among them is the service's non_finite at its pointer."""
    scene = block_scene()
    xs = path_positions(scene)
    with ntscontact.Client(daemon.base) as client:
        first = client.contact(ntscontact.Scene.from_dict(with_positions(scene, xs[0])))
        plain = first.history
        assert plain, "the block rubs: anchors to carry"
        as_numpy = [dict(a, nodes=np.asarray(a["nodes"]), param=np.float64(a["param"])) for a in plain]
        moved = ntscontact.Scene.from_dict(with_positions(scene, xs[1]))
        want = client.contact(moved, history=plain)
        got = client.contact(moved, history=as_numpy)
        assert np.array_equal(got.force_array(), want.force_array())
        bad = [dict(a) for a in plain]
        bad[-1]["param"] = np.float64("nan")
        with pytest.raises(ntscontact.InvalidScene) as exc:
            client.contact(moved, history=bad)
        assert (exc.value.code, exc.value.pointer) == ("non_finite", f"/history/{len(bad) - 1}/param")


def test_the_client_goes_on_from_a_history_and_commits(daemon):
    """Client.contact(scene, history=...) is the stateless chain; Session.step
    with commit=False leaves the history, as the service says."""
    scene = block_scene()
    xs = path_positions(scene)
    chain = stateless_chain(daemon, scene, xs[:5])
    client = ntscontact.Client(daemon.base)
    history = None
    for x, want in zip(xs[:5], chain):
        res = client.contact(ntscontact.Scene.from_dict(with_positions(scene, x)), history=history)
        assert np.array_equal(res.force_array(), np.concatenate([np.asarray(b["forces"]) for b in want["bodies"]]))
        assert [c.state for c in res.contacts] == [c["state"] for c in want["contacts"]]
        assert np.array_equal(res.tangential_forces(), np.array([c["tangential_force"] for c in want["contacts"]]))
        assert res.summary.dissipation == want["summary"]["dissipation"]
        history = res.history
    with client.session(ntscontact.Scene.from_dict(scene)) as s:
        for x in xs[:3]:
            s.step(x)
        trial = [s.step(xs[4], commit=False).force_array().copy() for _ in range(2)]
        assert np.array_equal(trial[0], trial[1])
        s.step(xs[3])
        assert np.array_equal(s.step(xs[4]).force_array(), res.force_array())


def test_the_tangent_through_a_session_is_the_trials_derivative(daemon):
    """In slip, the tangent a session answers (a general, non-symmetric scipy
    matrix) is minus the derivative of the forces of trials with commit=False
    from the same committed history, by central differences."""
    pytest.importorskip("scipy")
    scene = block_scene(outputs=("forces", "stiffness"))
    xs = path_positions(scene)
    client = ntscontact.Client(daemon.base)
    with client.session(ntscontact.Scene.from_dict(scene)) as s:
        for x in xs[:4]:
            s.step(x)
        x = xs[4]
        res = s.step(x, commit=False, outputs=["forces", "stiffness", "contacts"])
        assert res.summary.slipping > 0
        K = res.stiffness.toarray()
        assert np.abs(K - K.T).max() > 1e-3 * np.abs(K).max()   # not symmetric in slip
        h = 1e-7
        worst = 0.0
        for j in range(2 * 7, 2 * 10):                          # the block's bottom nodes, x and y
            e = np.zeros(x.size)
            e[j] = h
            fp = s.step(x + e.reshape(-1, 2), commit=False, outputs=["forces"]).force_array().ravel()
            fm = s.step(x - e.reshape(-1, 2), commit=False, outputs=["forces"]).force_array().ravel()
            col = -(fp - fm) / (2 * h)
            worst = max(worst, float(np.abs(col - K[:, j]).max() / np.abs(K).max()))
        assert worst < 1e-6, worst


def test_a_lost_friction_history_is_said_after_the_step(daemon):
    """A session the service lost is created anew and the step repeated;
    with friction its history is gone, and an IncompleteResultWarning says
    so once the step is done: as an error (warnings made errors), the step
    is taken all the same and the session holds its positions. It was
    raised in the middle of the step: the step not repeated, the client
    still holding the positions before it while the service held the
    scene's first."""
    import warnings

    scene = ntscontact.Scene.from_dict(block_scene())
    path = path_positions(block_scene(), steps=3)
    with ntscontact.Client(daemon.base) as client, client.session(scene) as s:
        s.step(path[0])
        requests.delete(f"{daemon.base}/v1/scenes/{s.id}", timeout=30)
        with warnings.catch_warnings():
            warnings.simplefilter("error", ntscontact.IncompleteResultWarning)
            with pytest.raises(ntscontact.IncompleteResultWarning, match="friction history is lost"):
                s.step(path[1])
        assert s.recreated == 1 and s.steps == 2
        again = s.step()  # the positions it holds: path[1], as the service does
        assert again.summary.contacts > 0
        with client.session(scene) as t:  # a session that starts there, sticking where it is
            want = t.step(path[1])
        assert np.array_equal(again.force_array(), want.force_array())
