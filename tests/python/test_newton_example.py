"""examples/newton_disks.py: Newton with the contact tangent converges, and
quadratically near the solution (the tangent is consistent)."""
import json
import os
import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("scipy")
REPO = pathlib.Path(__file__).resolve().parents[2]


def test_newton_converges_quadratically(tmp_path, paths):
    out = tmp_path / "runs.json"
    r = subprocess.run([sys.executable, str(REPO / "examples" / "newton_disks.py"), "--rings", "4", "--no-fire",
                        "--tol", "1e-9", "--json", str(out)], capture_output=True, text=True, timeout=300,
                       env={**os.environ, "NTS_BUILD_DIR": str(paths.build)})
    assert r.returncode == 0, r.stdout + r.stderr
    run = json.loads(out.read_text())[0]
    h = run["history"]
    assert run["converged"] and h[-1] < 1e-9 and run["iterations"] <= 20
    # Quadratic: some step near the solution goes from r < 1e-1 to at most r^2 times a modest constant.
    assert any(b <= 100.0 * a * a and a < 1e-1 for a, b in zip(h, h[1:])), h
