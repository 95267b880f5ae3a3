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
