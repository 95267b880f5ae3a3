"""examples/self_contact_ring.py: a ring squeezed flat between two plates
until its inside meets itself. With self-contact the two sides of the inside
press on each other (a penalty's small overlap); without it they overlap by
as much as the plates squeeze the walls."""
import json
import os
import subprocess
import sys

from conftest import BUILD, REPO


def run(tmp_path, *flags):
    out = tmp_path / f"ring{len(flags)}.json"
    env = dict(os.environ)
    if os.environ.get("NTS_SANITIZED") != "1":  # the build's engine (a sanitized one cannot load into Python)
        env["NTSCONTACT_LIBRARY"] = str(BUILD / "lib" / "libntscontact_engine.so")
    r = subprocess.run([sys.executable, str(REPO / "examples" / "self_contact_ring.py"), "--tiny", "--json", str(out),
                        *flags], capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(out.read_text())


def test_the_inside_meets_itself_only_with_self_contact(tmp_path):
    on, off = run(tmp_path), run(tmp_path, "--no-self")
    squeeze = 2.0 * on["wall"] - 2.0 * on["stages"][-1]["half_gap"]
    assert squeeze > 0.0
    # on: the two sides in contact, overlapping by the penalty's small amount
    assert on["self_contacts"] > 0 and on["inner_overlap"] < 0.1 * squeeze
    assert on["max_penetration"] < 0.1 * on["wall"]
    # off: nothing holds them apart
    assert off["self_contacts"] == 0 and off["inner_overlap"] > 0.5 * squeeze
    # before the plates come close, no self-contact at all
    assert all(s["self_contacts"] == 0 for s in on["stages"][: len(on["stages"]) // 2])


def test_the_squeezed_ring_has_the_same_contacts_at_any_radius(monkeypatch):
    """The ring's last state evaluated again with explicit radii up to more
    than its wall: the same contacts and energy as the default radius, and
    no self-contact through a wall (docs/model.md §16: (C) is asked of the
    closest opposed face only; asked of each, a radius past the wall gave
    the outer faces of the two pressed walls contacts with each other's far
    face, gap about -(2 wall - overlap), energy 1.5e4 times the default's)."""
    import pytest
    if os.environ.get("NTS_SANITIZED") == "1":
        pytest.skip("a sanitized library cannot be loaded into Python")
    monkeypatch.setenv("NTSCONTACT_LIBRARY", str(BUILD / "lib" / "libntscontact_engine.so"))
    monkeypatch.syspath_prepend(str(REPO / "examples"))
    import self_contact_ring as ring
    import ntscontact
    summary, _, scene, _ = ring.run(32, 10, True, 1e-3, 20000, 5000.0)
    doc = json.loads(scene.to_json())
    doc["options"].pop("outputs", None)
    wall = summary["wall"]
    got = []
    with ntscontact.Engine() as engine:
        for radius in (None, 0.35, 1.0):
            d = json.loads(json.dumps(doc))
            if radius is not None:
                d["options"]["search_radius"] = radius
            r = json.loads(engine.contact_json(d, ["energy", "contacts"]))
            own = [c for c in r["contacts"] if c["slave"]["body"] == c["master"]["body"] == "ring"]
            assert own and all(c["gap"] > -0.5 * wall for c in own)
            got.append((r["summary"]["contacts"], len(own), r["summary"]["energy"]))
    assert got[1] == got[0] and got[2] == got[0]
