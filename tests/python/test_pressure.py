"""The `pressure` output (docs/model.md (21)): per body, per node, the normal
contact traction on the node as a slave, the sum of -eps g over its active
contacts divided by its tributary length. Valid against result.schema.json,
equal to |slave force| / l computed here from the contacts, -eps g at a node
of one contact with "length" scaling, and the same through every door (CLI,
HTTP, the Python client's Result.pressure, a session's JSON step, VTK)."""
import json
import subprocess

import jsonschema
import numpy as np
import pytest
import requests

from conftest import CLI, run_cli_json

ntscontact = pytest.importorskip("ntscontact")

run = run_cli_json


def two_disks(scaling="node"):
    t = 2 * np.pi * np.arange(20) / 20
    s = 2 * np.pi * (np.arange(14) + 0.3) / 14
    return {"version": 1, "options": {"penalty": 1000.0, "alpha": 0.2, "search_radius": 0.3,
                                       "penalty_scaling": scaling},
            "bodies": [{"id": "a", "nodes": np.c_[np.cos(t), np.sin(t)].tolist()},
                       {"id": "b", "nodes": np.c_[1.85 + np.cos(s), 0.07 + np.sin(s)].tolist()}]}


def tributary(nodes):
    """Half of the two segments at each node of a one-loop body (§10)."""
    x = np.asarray(nodes)
    seg = np.hypot(*(np.roll(x, -1, axis=0) - x).T)  # segment k: node k to k + 1
    return 0.5 * (seg + np.roll(seg, 1))


@pytest.mark.parametrize("scaling", ["node", "length"])
def test_pressure_is_the_slave_force_over_the_tributary_length(schemas, scaling):
    doc = two_disks(scaling)
    out = run(doc, "--outputs", "pressure,contacts")
    jsonschema.validate(out, schemas["result"])
    assert [b["id"] for b in out["bodies"]] == ["a", "b"]
    assert all(set(b) == {"id", "pressure"} for b in out["bodies"])  # no forces unless asked
    assert out["summary"]["contacts"] > 2
    ids = [b["id"] for b in doc["bodies"]]
    single = 0
    for k, body in enumerate(doc["bodies"]):
        p = np.array(out["bodies"][k]["pressure"])
        assert p.shape == (len(body["nodes"]),)
        force = np.zeros(len(p))
        count = np.zeros(len(p), dtype=int)
        for c in out["contacts"]:
            if c["slave"]["body"] == ids[k]:
                force[c["slave"]["node"]] += np.hypot(*c["force"])
                count[c["slave"]["node"]] += 1
        want = force / tributary(body["nodes"])
        assert np.all(p[count == 0] == 0.0) and np.all(p[count > 0] > 0.0)
        assert np.allclose(p, want, rtol=1e-12, atol=0.0), (p, want)
        if scaling == "length":  # one contact at a node: p = -eps g
            for c in out["contacts"]:
                if c["slave"]["body"] == ids[k] and count[c["slave"]["node"]] == 1:
                    assert p[c["slave"]["node"]] == pytest.approx(-1000.0 * c["gap"], rel=1e-12)
                    single += 1
    assert scaling == "node" or single > 0


def test_pressure_with_forces_leaves_the_forces_unchanged(schemas):
    doc = two_disks()
    both = run(doc, "--outputs", "forces,pressure")
    jsonschema.validate(both, schemas["result"])
    forces = run(doc, "--outputs", "forces")
    assert [b["forces"] for b in both["bodies"]] == [b["forces"] for b in forces["bodies"]]
    assert both["summary"]["energy"] == forces["summary"]["energy"]
    assert both["bodies"][0]["pressure"] == run(doc, "--outputs", "pressure")["bodies"][0]["pressure"]


def test_pressure_through_http_the_client_and_a_session(daemon, tmp_path):
    doc = two_disks("length")
    doc["options"]["outputs"] = ["pressure"]
    cli = run(doc)
    r = requests.post(daemon.url("/v1/contact"), json=doc, timeout=30)
    assert r.json()["bodies"] == cli["bodies"]
    want = {b["id"]: np.array(b["pressure"]) for b in cli["bodies"]}
    with ntscontact.Client(daemon.base, timeout=30) as c, c.session(doc) as s:
        full = c.contact(ntscontact.Scene.from_dict(doc), outputs=["pressure"])
        step = s.contact(s.positions(), outputs=["forces", "pressure"])  # a binary answer
        stiff = s.contact(s.positions(), outputs=["forces", "stiffness", "pressure"])  # after the triplets
        assert len(stiff.stiffness_triplets()[2]) > 0
        for res in (full, step, stiff):
            assert set(res.pressure) == {"a", "b"}
            for i, p in res.pressure.items():
                assert p.dtype == np.float64 and np.array_equal(p, want[i])
            assert np.array_equal(res.pressure_array(), np.concatenate([want["a"], want["b"]]))
        assert step.forces and not full.forces
        with pytest.raises(KeyError):
            s.contact(outputs=["forces"]).pressure_array()
        # VTK: the Python writer and the C tool give the same point field
        meshio = pytest.importorskip("meshio")
        full.to_vtk(tmp_path / "py.vtu")
        scene = tmp_path / "scene.json"
        scene.write_text(json.dumps(doc))
        subprocess.run([str(CLI), "--vtk", str(tmp_path / "c.vtu"), str(scene)], check=True, capture_output=True,
                       timeout=60)
        a, b = meshio.read(tmp_path / "py.vtu"), meshio.read(tmp_path / "c.vtu")
        n = len(full.pressure_array())
        assert np.array_equal(a.point_data["pressure"].ravel()[:n], full.pressure_array())
        assert np.array_equal(b.point_data["pressure"].ravel()[:n], full.pressure_array())


def test_a_binary_step_carries_the_pressure(daemon):
    """Raw: 16 N bytes of forces, then N float64 pressures, equal bit for bit to
    the JSON step's."""
    doc = two_disks("length")
    r = requests.post(daemon.url("/v1/scenes"), json=doc, timeout=30)
    assert r.status_code == 201, r.text
    url = daemon.url(f"/v1/scenes/{r.json()['id']}/contact")
    js = requests.post(url + "?outputs=forces,pressure", timeout=30).json()
    b = requests.post(url + "?outputs=forces,pressure", headers={"Accept": "application/octet-stream"}, timeout=30)
    assert b.status_code == 200 and b.headers["Content-Type"] == "application/octet-stream"
    n = sum(len(x["nodes"]) for x in doc["bodies"])
    assert len(b.content) == 16 * n + 8 * n
    p = np.frombuffer(b.content, dtype="<f8", offset=16 * n)
    assert np.array_equal(p, np.concatenate([np.array(x["pressure"]) for x in js["bodies"]]))
    assert p.max() > 0
    plain = requests.post(url + "?outputs=forces", headers={"Accept": "application/octet-stream"}, timeout=30)
    assert len(plain.content) == 16 * n
