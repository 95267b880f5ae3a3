"""The scene fields of issue 12, positively: a body's own "alpha" and "role",
options.penalty_scaling; valid against the schema, honoured by the CLI, the
daemon (sessions included) and the Python client, which checks them first."""
import json
import math
import os
import pathlib
import subprocess

import jsonschema
import numpy as np
import pytest

ntscontact = pytest.importorskip("ntscontact")

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"


def disk(cx, cy, r, n, phase=0.0):
    t = phase + 2 * math.pi * np.arange(n) / n
    return np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]


def container(lo, hi, w):
    nodes = [[lo - w, lo - w], [hi + w, lo - w], [hi + w, hi + w], [lo - w, hi + w],
             [lo, lo], [lo, hi], [hi, hi], [hi, lo]]
    return {"nodes": nodes, "loops": [[0, 1, 2, 3], [4, 5, 6, 7]]}


def scene(**options):
    box = container(0.0, 12.0, 1.0)
    return {"version": 1, "options": {"penalty": 100.0, "alpha": 0.2, "search_radius": 0.5, **options},
            "bodies": [{"id": "box", **box, "alpha": 0.0, "role": "master"},
                       {"id": "a", "nodes": disk(0.98, 0.98, 1.0, 64).tolist()},
                       {"id": "b", "nodes": disk(2.9, 0.98, 1.0, 16, 0.1).tolist(), "role": "slave"}]}


def evaluate(doc, *flags):
    r = subprocess.run([str(CLI), *flags, "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr.decode()
    return json.loads(r.stdout)


def test_fields_are_valid_and_honoured(schemas):
    doc = scene(outputs=["forces", "contacts", "gaps"])
    jsonschema.validate(doc, schemas["scene"])
    out = evaluate(doc)
    jsonschema.validate(out, schemas["result"])
    assert out["summary"]["contacts"] > 0
    for g in out["gaps"]:
        assert g["slave"]["body"] != "box"           # a master's nodes are never slaves
        assert g["master"]["body"] != "b"            # a slave body offers no surface
    on_box = [c for c in out["contacts"] if c["master"]["body"] == "box"]
    assert on_box and all(c["master"]["kind"] != "corner" for c in on_box)  # the box's own alpha = 0
    assert min(c["gap"] for c in on_box) > -0.03     # the real 0.02, no rounded-corner artefact
    assert any(c["slave"]["body"] == "b" and c["master"]["body"] == "a" for c in out["contacts"])
    box_force = np.abs(np.array(out["bodies"][0]["forces"])).sum()
    assert box_force > 0.0                           # the reaction on the obstacle
    # Without the box's own alpha, the scene's 0.2 rounds its corner: a spurious deep contact.
    rounded = scene(outputs=["contacts"])
    del rounded["bodies"][0]["alpha"]
    worst = min(c["gap"] for c in evaluate(rounded)["contacts"] if c["master"]["body"] == "box")
    assert worst < -0.3


def test_penalty_per_length_scales_each_slave_by_its_tributary_length():
    doc = scene(outputs=["contacts"])
    per_node = evaluate(doc)
    doc["options"]["penalty_scaling"] = "length"
    per_length = evaluate(doc)
    assert [c["gap"] for c in per_node["contacts"]] == [c["gap"] for c in per_length["contacts"]]
    bodies = {b["id"]: np.array(b["nodes"]) for b in doc["bodies"] if "loops" not in b}
    energy = 0.0
    for c in per_length["contacts"]:
        nodes = bodies[c["slave"]["body"]]
        k, n = c["slave"]["node"], len(nodes)
        trib = 0.5 * (np.linalg.norm(nodes[k] - nodes[k - 1]) + np.linalg.norm(nodes[(k + 1) % n] - nodes[k]))
        energy += 0.5 * 100.0 * trib * c["gap"] ** 2
    assert per_length["summary"]["energy"] == pytest.approx(energy, rel=1e-12)
    assert per_length["summary"]["energy"] < per_node["summary"]["energy"]  # tributary lengths < 1


def test_python_scene_carries_the_fields(schemas):
    doc = scene(penalty_scaling="length")
    s = ntscontact.Scene.from_dict(doc)
    assert s.penalty_scaling == "length"
    assert s.body("box").alpha == 0.0 and s.body("box").role == "master" and s.body("b").role == "slave"
    again = s.to_dict()
    jsonschema.validate(again, schemas["scene"])
    assert again["bodies"][0]["alpha"] == 0.0 and again["bodies"][2]["role"] == "slave"
    assert again["options"]["penalty_scaling"] == "length"
    x = s.positions()
    assert x.shape == (8 + 64 + 16, 2)
    s.set_positions(x + 1.0)
    assert np.array_equal(s.positions(), x + 1.0)
    with pytest.raises(ntscontact.InvalidScene):
        s.set_positions(x[:-1])
    with pytest.raises(ntscontact.InvalidScene) as e:
        s.add_body(disk(0, 0, 1, 8), id=2 ** 53)
    assert e.value.pointer == "/bodies/3/id"
    with pytest.raises(ntscontact.InvalidScene):
        s.add_body(disk(0, 0, 1, 8), alpha=0.6)
    with pytest.raises(ntscontact.InvalidScene):
        s.add_body(disk(0, 0, 1, 8), role="wall")
    with pytest.raises(ntscontact.InvalidScene):
        ntscontact.Scene(penalty=1.0, penalty_scaling="area")


def test_sessions_keep_the_fields_and_the_reference_lengths(daemon):
    """A session measures the tributary lengths once, at creation (its reference
    configuration); a full call measures them at the positions it is given."""
    doc = scene(penalty_scaling="length", outputs=["forces", "energy", "contacts"])
    with ntscontact.Client(daemon.base, timeout=60) as c, c.session(doc) as s:
        x = s.positions()
        x[8:] += [0.003, -0.002]  # a rigid shift of the disks: lengths unchanged up to round-off
        got = s.contact(x, outputs=["forces", "energy"])
        moved = ntscontact.Scene.from_dict(doc)
        moved.set_positions(x)
        want = c.contact(moved, outputs=["forces", "energy"])
        assert np.allclose(got.force_array(), want.force_array(), rtol=1e-12, atol=1e-14)
        # Now stretch disk "a" by 2% about its centre: the session still uses the
        # lengths at creation, as the energy recomputed here from them shows.
        ca = x[8:72].mean(axis=0)
        x[8:72] = ca + 1.02 * (x[8:72] - ca)
        stretched = s.contact(x, outputs=["contacts"])
        ref = {b["id"]: np.array(b["nodes"]) for b in doc["bodies"] if "loops" not in b}
        energy = 0.0
        for k in stretched.contacts:
            nodes = ref[k.slave_body]
            i, n = k.slave_node, len(nodes)
            trib = 0.5 * (np.linalg.norm(nodes[i] - nodes[i - 1]) + np.linalg.norm(nodes[(i + 1) % n] - nodes[i]))
            energy += 0.5 * 100.0 * trib * k.gap ** 2
        assert stretched.energy == pytest.approx(energy, rel=1e-12)


def test_reference_sets_the_tributary_lengths(schemas):
    """A body's "reference" is where penalty per length measures its tributary
    lengths (issue 22 §4): the nodes themselves give the very same bits as no
    reference, another configuration gives its own lengths."""
    doc = scene(penalty_scaling="length", outputs=["forces", "contacts"])
    plain = evaluate(doc)
    same = json.loads(json.dumps(doc))
    for b in same["bodies"]:
        b["reference"] = b["nodes"]
    jsonschema.validate(same, schemas["scene"])
    got = evaluate(same)
    got["summary"].pop("elapsed_ms"), plain["summary"].pop("elapsed_ms")
    assert got == plain
    # Disk "a" measured at twice its size: its tributary lengths double.
    bigger = json.loads(json.dumps(doc))
    ref = 2.0 * np.array(bigger["bodies"][1]["nodes"])
    bigger["bodies"][1]["reference"] = ref.tolist()
    out = evaluate(bigger)
    assert [c["gap"] for c in out["contacts"]] == [c["gap"] for c in plain["contacts"]]
    lengths = {b["id"]: np.array(b.get("reference", b["nodes"])) for b in bigger["bodies"] if "loops" not in b}
    energy = 0.0
    for c in out["contacts"]:
        nodes = lengths[c["slave"]["body"]]
        k, n = c["slave"]["node"], len(nodes)
        trib = 0.5 * (np.linalg.norm(nodes[k] - nodes[k - 1]) + np.linalg.norm(nodes[(k + 1) % n] - nodes[k]))
        energy += 0.5 * 100.0 * trib * c["gap"] ** 2
    assert out["summary"]["energy"] == pytest.approx(energy, rel=1e-12)
    assert out["summary"]["energy"] > plain["summary"]["energy"]


def test_python_scene_carries_the_reference(schemas):
    doc = scene(penalty_scaling="length")
    doc["bodies"][1]["reference"] = (2.0 * np.array(doc["bodies"][1]["nodes"])).tolist()
    s = ntscontact.Scene.from_dict(doc)
    assert s.body("a").reference.shape == (64, 2) and s.body("b").reference is None
    again = s.to_dict()
    jsonschema.validate(again, schemas["scene"])
    assert again["bodies"][1]["reference"] == doc["bodies"][1]["reference"]
    assert "reference" not in again["bodies"][2]
    with pytest.raises(ntscontact.InvalidScene) as e:
        s.add_body(disk(0, 0, 1, 8), reference=disk(0, 0, 1, 7))
    assert e.value.pointer == "/bodies/3/reference" and e.value.code == "invalid_value"
    bad = disk(0, 0, 1, 8)
    bad[5, 1] = np.nan
    with pytest.raises(ntscontact.InvalidScene) as e:
        s.add_body(disk(0, 0, 1, 8), reference=bad)
    assert e.value.pointer == "/bodies/3/reference/5" and e.value.code == "non_finite"


def test_the_schema_bounds_coordinates_as_the_program_does(schemas):
    """A node's coordinate beyond +-1e100 is out_of_range for the program and
    refused by scene.schema.json too (it took any number); at the bound both
    take it. A session step's positions likewise."""
    validator = jsonschema.Draft202012Validator(schemas["scene"])
    step = jsonschema.Draft202012Validator({**schemas["session"]["$defs"]["step"],
                                            "$defs": schemas["session"]["$defs"]})
    for x, ok in ((1e100, True), (-1e100, True), (1.0000000000000002e100, False), (-2e100, False)):
        doc = {"version": 1, "options": {"penalty": 1.0},
               "bodies": [{"id": "a", "nodes": [[0.0, 0.0], [x, 0.0], [0.0, 1e100]]}]}
        r = subprocess.run([str(CLI), "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
        assert (r.returncode == 0) == ok, (x, r.stderr)
        if not ok:
            assert b"out_of_range" in r.stderr, r.stderr
        assert validator.is_valid(doc) == ok, x
        assert step.is_valid({"positions": [[0.0, 0.0], [x, 0.0], [0.0, 1e100]]}) == ok, x
