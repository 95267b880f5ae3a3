"""Self-contact through every door (issue 29, docs/model.md §16): a body's
"self_contact" in the scene JSON, the CLI, the daemon, sessions (binary and
JSON steps equal the stateless call), the in-process engine, the Python
Scene, VTK; its faults named by pointer."""
import json
import subprocess

import numpy as np
import pytest
import requests

import os

from conftest import BUILD, CLI, positions_of, with_positions

ntscontact = pytest.importorskip("ntscontact")
JSON = {"Content-Type": "application/json"}


def horseshoe(gap, R=1.0, w=0.3, L=2.0, arc=40, arm=20):
    """A U whose arms are bent in above y = 0.2 until their inner walls are
    `gap` apart (negative: overlapping by -gap), as in tests/core/test_self_contact.c."""
    pts = [(R * np.cos(np.pi + np.pi * i / (arc - 1)), R * np.sin(np.pi + np.pi * i / (arc - 1))) for i in range(arc)]
    pts += [(R, L * i / (arm - 1)) for i in range(1, arm)]
    pts += [(R - w, L * (arm - 1 - i) / (arm - 1)) for i in range(arm)]
    pts += [((R - w) * np.cos(np.pi + np.pi * i / (arc - 1)), (R - w) * np.sin(np.pi + np.pi * i / (arc - 1)))
            for i in range(arc - 2, 0, -1)]
    pts += [(-(R - w), L * i / (arm - 1)) for i in range(arm)]
    pts += [(-R, L * i / (arm - 1)) for i in range(arm - 2, 0, -1)]
    p = np.array(pts)
    f = np.clip((p[:, 1] - 0.2) / 0.5, 0.0, 1.0)
    p[:, 0] -= np.sign(p[:, 0]) * f * ((R - w) - gap / 2.0)
    return p


def scene(gap=-0.03, self_contact=True, outputs=("forces", "energy", "virial", "contacts")):
    body = {"id": "shoe", "nodes": horseshoe(gap).tolist()}
    if self_contact is not None:
        body["self_contact"] = self_contact
    return {"options": {"penalty": 100.0, "alpha": 0.2, "search_radius": 0.3, "outputs": list(outputs)},
            "bodies": [body]}


def cli(doc, *flags):
    r = subprocess.run([str(CLI), *flags, "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    return r.returncode, json.loads(r.stdout or r.stderr or b"{}") if r.stdout else r.stderr.decode()


def test_the_cli_and_the_daemon_find_the_overlap(daemon, schemas):
    from jsonschema import Draft202012Validator
    doc = scene()
    Draft202012Validator(schemas["scene"]).validate(doc)
    rc, res = cli(doc)
    assert rc == 0
    Draft202012Validator(schemas["result"]).validate(res)
    contacts = res["contacts"]
    assert len(contacts) == 24 and all(c["slave"]["body"] == c["master"]["body"] == "shoe" for c in contacts)
    r = requests.post(daemon.url("/v1/contact"), data=json.dumps(doc), headers=JSON, timeout=60).json()
    for d in (r, res):
        d["summary"].pop("elapsed_ms")
    assert r == res
    # off (or absent): the overlap goes unseen, as before
    for off in (False, None):
        rc, res = cli(scene(self_contact=off))
        assert rc == 0 and res["summary"]["contacts"] == 0
    # at rest: none
    rc, res = cli(scene(gap=0.2))
    assert rc == 0 and res["summary"]["contacts"] == 0


def test_a_bad_value_is_named(daemon):
    for bad in (1, "yes", None):
        doc = scene()
        doc["bodies"][0]["self_contact"] = bad
        r = requests.post(daemon.url("/v1/contact"), data=json.dumps(doc), headers=JSON, timeout=60)
        assert r.status_code == 400
        err = r.json()["error"]
        assert err["code"] == "invalid_type" and err["pointer"] == "/bodies/0/self_contact"
    with pytest.raises(ntscontact.InvalidScene) as info:
        ntscontact.Scene(penalty=1.0).add_body(horseshoe(0.1), self_contact="yes")
    assert info.value.pointer == "/bodies/0/self_contact"


def test_sessions_equal_the_stateless_call(daemon):
    doc = scene(outputs=("forces", "energy", "virial"))
    pos0 = positions_of(doc)
    rng = np.random.default_rng(29)
    with ntscontact.Client(daemon.base, timeout=60) as client, client.session(doc) as s:
        for k in range(6):
            pos = pos0 + rng.normal(scale=2e-3, size=pos0.shape)
            got = s.contact(pos, outputs=["forces", "energy", "virial"] if k % 2 else ["forces", "contacts"])
            want = client.contact(with_positions(doc, pos), outputs=["forces", "energy", "virial"] if k % 2
                                  else ["forces", "contacts"])
            assert np.array_equal(got.force_array(), want.force_array())
            assert got.summary.energy == want.summary.energy and got.summary.contacts == want.summary.contacts > 0
            assert got.contacts == want.contacts


def test_the_python_scene_and_the_engine(daemon):
    sc = ntscontact.Scene(penalty=100.0, alpha=0.2, search_radius=0.3, outputs=["forces", "contacts"])
    sc.add_body(horseshoe(-0.03), id="shoe", self_contact=True)
    assert sc.to_dict()["bodies"][0]["self_contact"] is True
    assert ntscontact.Scene.from_dict(sc.to_dict()).to_dict() == sc.to_dict()
    with ntscontact.Client(daemon.base, timeout=60) as client:
        want = client.contact(sc)
    # the build's engine, as the daemon's (a sanitized library cannot load into Python: the bundled one then)
    lib = None if os.environ.get("NTS_SANITIZED") == "1" else BUILD / "lib" / "libntscontact_engine.so"
    got = ntscontact.Engine(library=lib).contact(sc)
    assert np.array_equal(got.force_array(), want.force_array()) and got.contacts == want.contacts
    assert len(got.contacts) == 24
    # the forces push the arms apart: the right arm's nodes (now left of x = 0) go right
    f = got.forces["shoe"]
    x = horseshoe(-0.03)
    for c in got.contacts:
        assert (x[c.slave_node, 0] < 0.0) == (f[c.slave_node, 0] > 0.0)


def test_vtk_draws_the_self_contacts(tmp_path):
    meshio = pytest.importorskip("meshio")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene()))
    out = tmp_path / "out.vtu"
    r = subprocess.run([str(CLI), "--vtk", str(out), "--outputs", "forces,contacts", str(path)], capture_output=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    mesh = meshio.read(out)
    kind = np.concatenate(mesh.cell_data["kind"])
    assert int((kind == 1).sum()) == len(res["contacts"]) == 24
