"""Issue 22 §1: a default never drops a contact, and an explicit search radius
that leaves contacts out says so, at every door: the result's "warnings"
(JSON), one line on the CLI's standard error, an NTS-Warnings header on a
binary session step, and an IncompleteResultWarning in Python."""
import json
import math
import subprocess
import warnings

import jsonschema
import numpy as np
import pytest
import requests

import ntscontact
from conftest import positions_of

PRESSED = 0.5  # how far the two disks overlap: far deeper than a segment


def disks(search_radius=None, n=48, overlap=PRESSED):
    """Two disks of radius 1 and n nodes, `overlap` into each other."""
    bodies = []
    for k, cx in enumerate((0.0, 2.0 - overlap)):
        th = 2 * math.pi * (np.arange(n) + 0.5 * k) / n
        bodies.append({"id": "ab"[k], "nodes": np.column_stack([cx + np.cos(th), np.sin(th)]).tolist()})
    options = {"penalty": 10.0, "alpha": 0.2, "outputs": ["forces", "energy", "contacts"]}
    if search_radius is not None:
        options["search_radius"] = search_radius
    return {"version": 1, "options": options, "bodies": bodies}


def cli(paths, scene, *flags):
    proc = subprocess.run([str(paths.cli), *flags, "-"], input=json.dumps(scene).encode(), capture_output=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr.decode()
    return json.loads(proc.stdout), proc.stderr.decode()


def test_default_finds_every_contact_and_says_nothing(paths, schemas):
    """The median segment (0.13) is far shorter than the overlap: the default
    still finds what a radius of a diameter finds, the same records."""
    default, err = cli(paths, disks())
    wide, err_wide = cli(paths, disks(search_radius=2.0))
    assert err == "" and err_wide == ""
    assert default["warnings"] == [] and wide["warnings"] == []
    assert default["summary"]["search_radius"] < 0.15
    assert default["summary"]["deep_contacts"] > 10
    assert default["contacts"] == wide["contacts"]
    assert default["summary"]["contacts"] == wide["summary"]["contacts"] > 20
    assert default["summary"]["energy"] == pytest.approx(wide["summary"]["energy"], rel=1e-12)
    assert default["summary"]["max_penetration"] == wide["summary"]["max_penetration"] > 0.2
    jsonschema.validate(default, schemas["result"])


def test_explicit_radius_says_what_it_leaves_out(paths, schemas):
    default, _ = cli(paths, disks())
    short, err = cli(paths, disks(search_radius=0.1))
    deeper = sum(1 for c in default["contacts"] if -c["gap"] > 0.1)
    assert deeper > 10
    assert short["summary"]["contacts"] == default["summary"]["contacts"] - deeper
    assert short["summary"]["deep_contacts"] == 0
    assert [(w["code"], w["count"]) for w in short["warnings"]] == [("penetration_beyond_radius", deeper)]
    jsonschema.validate(short, schemas["result"])
    # One line on standard error, code, count and message.
    lines = err.splitlines()
    assert lines == [f"ntscontact: warning: penetration_beyond_radius ({deeper}): {short['warnings'][0]['message']}"]
    # --frames says it frame by frame.


def test_frames_say_it_frame_by_frame(paths, tmp_path):
    scene = disks(search_radius=0.1)
    scene_path = tmp_path / "scene.json"
    scene_path.write_text(json.dumps(scene))
    pos = positions_of(scene)
    apart = pos.copy()
    apart[48:, 0] += 5.0  # frame 1: the disks apart, nothing to say
    frames = tmp_path / "frames.bin"
    frames.write_bytes(np.concatenate([pos, apart, pos]).astype("<f8").tobytes())
    proc = subprocess.run([str(paths.cli), "--frames", str(frames), str(scene_path)], capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr.decode()
    results = [json.loads(line) for line in proc.stdout.decode().splitlines()]
    assert [len(r["warnings"]) for r in results] == [1, 0, 1]
    lines = proc.stderr.decode().splitlines()
    assert [line.split(":")[1].strip() for line in lines] == ["frame 0", "frame 2"]
    assert all("warning: penetration_beyond_radius" in line for line in lines)


def test_daemon_json_and_binary_answers_say_it(daemon):
    r = requests.post(daemon.url("/v1/contact"), json=disks(search_radius=0.1), timeout=30)
    assert r.status_code == 200
    doc = r.json()
    (w,) = doc["warnings"]
    assert w["code"] == "penetration_beyond_radius" and w["count"] > 10
    # A session's binary step: the forces as bytes, the warning in a header.
    scene = disks(search_radius=0.1)
    scene["options"]["outputs"] = ["forces", "energy"]
    r = requests.post(daemon.url("/v1/scenes"), json=scene, timeout=30)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    pos = positions_of(scene)
    step = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=pos.astype("<f8").tobytes(),
                         headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                         timeout=30)
    assert step.status_code == 200
    assert step.headers["NTS-Warnings"] == f"penetration_beyond_radius={w['count']}"
    assert step.headers["NTS-Deep-Contacts"] == "0"
    apart = pos.copy()
    apart[48:, 0] += 5.0
    step = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=apart.astype("<f8").tobytes(),
                         headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                         timeout=30)
    assert step.status_code == 200 and "NTS-Warnings" not in step.headers
    requests.delete(daemon.url(f"/v1/scenes/{sid}"), timeout=30)


def test_python_client_warns(daemon):
    scene = ntscontact.Scene.from_json(json.dumps(disks(search_radius=0.1)))
    with ntscontact.Client(daemon.base) as client:
        with pytest.warns(ntscontact.IncompleteResultWarning, match="penetration_beyond_radius"):
            res = client.contact(scene)
        (w,) = res.warnings
        assert w.code == "penetration_beyond_radius" and w.count > 10
        with client.session(scene) as session:
            with pytest.warns(ntscontact.IncompleteResultWarning, match="penetration_beyond_radius"):
                step = session.contact(positions_of(disks()), outputs=["forces", "energy"])
            assert [x.code for x in step.warnings] == ["penetration_beyond_radius"]
            assert step.warnings[0].count == w.count
            # Each names the caller's line, whichever door: a session's
            # contact and step (which calls contact), the client's contact;
            # it named the client's own line for step().
            for door in (session.contact, session.step, client.contact):
                with pytest.warns(ntscontact.IncompleteResultWarning) as got:
                    door(scene) if door == client.contact else door(positions_of(disks()))
                assert [x.filename for x in got] == [__file__], [(x.filename, x.lineno) for x in got]
        # The default: every contact, no warning.
        scene.search_radius = None
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            full = client.contact(scene)
        assert full.warnings == [] and full.summary.deep_contacts > 10
        assert full.summary.contacts == res.summary.contacts + w.count
