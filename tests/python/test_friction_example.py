"""examples/friction_shear.py: an elastic disk pressed on a block and sheared
with Coulomb friction, Newton with the non-symmetric tangent and a commit per
converged load step: the stick zone shrinks from its edges, then the disk
slides with Q = mu P, dissipating mu P per unit of slide."""
import json
import os
import subprocess
import sys

import pytest

from conftest import REPO

pytest.importorskip("scipy")


def test_friction_shear_sticks_then_slides(tmp_path, paths):
    out = tmp_path / "steps.json"
    r = subprocess.run([sys.executable, str(REPO / "examples" / "friction_shear.py"), "--json", str(out)],
                       capture_output=True, text=True, timeout=300, env={**os.environ, "NTS_BUILD_DIR": str(paths.build)})
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(out.read_text())
    mu, steps = doc["mu"], doc["steps"]
    assert all(s["converged"] and s["residual"] < 1e-8 for s in steps)
    assert all(s["dissipation"] >= 0.0 for s in steps)
    shear = [s for s in steps if s["shear"] > 0]
    assert shear[0]["slipping"] == 0 and shear[0]["sticking"] > 0            # first all stick
    assert any(s["sticking"] > 0 and s["slipping"] > 0 for s in shear)       # partial slip
    for a, b in zip(shear, shear[1:]):                                       # the stick zone only shrinks
        assert b["sticking"] <= a["sticking"]
    last, before = shear[-1], shear[-2]
    assert last["sticking"] == 0 and last["slipping"] == last["contacts"] > 0
    assert last["Q"] == pytest.approx(mu * last["P"], rel=1e-9)              # sliding: Q = mu P
    # steady sliding: the step's slip is the shear increment, its heat mu P times it
    assert last["dissipation"] == pytest.approx(mu * last["P"] * (last["shear"] - before["shear"]), rel=1e-6)
