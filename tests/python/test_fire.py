"""examples/fire_packing.py: FIRE on its own (a quadratic bowl, no service) and the
packing example on its tiny configuration against the daemon: it reaches its
force residual, and the service, asked again, agrees that the packing is in
equilibrium."""
import importlib.util
import json
import math
import subprocess
import sys

import numpy as np
import pytest

ntscontact = pytest.importorskip("ntscontact")


@pytest.fixture(scope="module")
def fp(paths):
    spec = importlib.util.spec_from_file_location("fire_packing", paths.examples / "fire_packing.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["fire_packing"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_fire_minimises_an_ill_conditioned_quadratic(fp):
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.standard_normal((20, 20)))
    k = q @ np.diag(np.geomspace(1e-2, 10.0, 20)) @ q.T  # condition number 1000
    xmin = rng.standard_normal((10, 2))

    def force(x):
        d = (x - xmin).reshape(-1)
        return 0.5 * d @ k @ d, -(k @ d).reshape(-1, 2)

    x, stats = fp.fire(force, np.zeros((10, 2)), 1e-10, 20000, 0.03)
    assert stats.converged and stats.residual < 1e-10
    assert np.abs(x - xmin).max() < 1e-7
    assert 0 < stats.iterations < 20000


def test_shape_forces_are_the_gradient(fp):
    rng = np.random.default_rng(1)
    t = np.linspace(0, 2 * np.pi, 10)[:-1]
    p = np.stack([np.cos(t), np.sin(t)], axis=1) + 0.05 * rng.standard_normal((9, 2))
    e, f = fp.shape_energy_forces(p, 0.7, 3.5, 1.3, 0.8)
    h = 1e-6
    for i in range(9):
        for c in range(2):
            q = p.copy()
            q[i, c] += h
            ep, _ = fp.shape_energy_forces(q, 0.7, 3.5, 1.3, 0.8)
            q[i, c] -= 2 * h
            em, _ = fp.shape_energy_forces(q, 0.7, 3.5, 1.3, 0.8)
            assert -(ep - em) / (2 * h) == pytest.approx(f[i, c], abs=1e-7)


def test_tiny_packing_reaches_its_residual(fp, daemon, paths, tmp_path):
    out = tmp_path / "runs.json"
    proc = subprocess.run([sys.executable, str(paths.examples / "fire_packing.py"), "--tiny", "--url", daemon.base,
                           "--json", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    doc = json.loads(out.read_text())
    tol = doc["config"]["tol"]
    assert tol == 1e-10 and [r["alpha"] for r in doc["runs"]] == [0.0, 0.25]
    table = proc.stdout.splitlines()
    for r in doc["runs"]:
        assert r["converged"] and r["residual"] < tol, r
        assert 0 < r["iterations"] < doc["config"]["max_iter"]
        assert r["contacts"] > 0 and r["touching_pairs"] >= doc["config"]["cells"] - 1
        assert math.isfinite(r["energy"]) and r["energy"] > r["contact_energy"] > 0
        assert any(line.split()[:2] == [f"{r['alpha']:.2f}", str(r["iterations"])] for line in table), table


def test_tiny_packing_is_in_equilibrium_for_the_service(fp, daemon):
    """Relax in-process with alpha > 0, then ask the service afresh: the cells' own
    forces and the contact forces cancel to the residual at every node."""
    cfg = fp.Config(cells=4, vertices=8, stages=8, alphas=(0.25,))
    with ntscontact.Client(daemon.base, timeout=30) as client:
        run, pk, res = fp.relax(client, cfg, 0.25)
        assert run.converged
        scene = ntscontact.Scene(penalty=cfg.penalty, alpha=0.25, search_radius=cfg.search_radius,
                                 periodic=(pk.box, pk.box))
        for i, p in enumerate(pk.nodes):
            scene.add_body(p, id=i)
        contact = client.contact(scene, outputs=["forces", "energy", "contacts"])
    total = []
    for i, p in enumerate(pk.nodes):
        _, f = fp.shape_energy_forces(p, pk.l0[i], pk.a0[i], cfg.ka, cfg.kl)
        total.append(f + contact.forces[i])
    total = np.concatenate(total)
    assert np.max(np.hypot(total[:, 0], total[:, 1])) < cfg.tol
    assert contact.summary.contacts == run.contacts > 0
    # contact is a real load: the largest contact force is far above the residual
    assert max(np.hypot(*c.force) for c in contact.contacts) > 1e6 * cfg.tol


def test_example_starts_its_own_daemon(paths, tmp_path):
    """Without --url the example starts ntscontactd from the build dir on a free
    port, and stops it when done."""
    import os

    env = dict(os.environ, NTS_BUILD_DIR=str(paths.build))
    out = tmp_path / "runs.json"
    proc = subprocess.run([sys.executable, str(paths.examples / "fire_packing.py"), "--tiny", "--alphas", "0.25",
                           "--json", str(out)], capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run,) = json.loads(out.read_text())["runs"]
    assert run["converged"] and run["residual"] < 1e-10
