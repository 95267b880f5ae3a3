"""`pip install ./clients/python`: the package builds and bundles the
in-process engine with the project's CMake, and installs without it (the HTTP
client working, the engine saying how to get it) where CMake is missing.

Installed with --target into a temporary directory (no network, no build
isolation: the .venv's setuptools), then imported from there ahead of the
editable install."""
import json
import os
import subprocess
import sys

import pytest

from conftest import REPO

pytest.importorskip("ntscontact")

PROBE = r"""
import json, sys, ntscontact
print(json.dumps({"file": ntscontact.__file__}))
try:
    e = ntscontact.Engine()
except ntscontact.EngineUnavailable as exc:
    print(json.dumps({"unavailable": str(exc)}))
    sys.exit(0)
r = e.contact(open(sys.argv[1]).read())
print(json.dumps({"library": str(e.library), "energy": r.summary.energy, "contacts": r.summary.contacts}))
"""


def pip_install(target, **env):
    e = dict(os.environ)
    e.pop("NTSCONTACT_LIBRARY", None)
    e.pop("NTSCONTACT_REQUIRE_ENGINE", None)
    e.update(env)
    return subprocess.run([sys.executable, "-m", "pip", "install", "-v", "--disable-pip-version-check", "--no-deps",
                           "--no-build-isolation", "--target", str(target), str(REPO / "clients" / "python")],
                          capture_output=True, text=True, env=e, timeout=900)


def probe(target):
    e = dict(os.environ, PYTHONPATH=str(target))
    e.pop("NTSCONTACT_LIBRARY", None)
    r = subprocess.run([sys.executable, "-c", PROBE, str(REPO / "examples" / "two_disks.json")],
                       capture_output=True, text=True, env=e, timeout=120, cwd=str(target))
    assert r.returncode == 0, r.stderr
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    assert lines[0]["file"].startswith(str(target))  # the installed copy, not the editable one
    return lines[1]


def test_pip_install_bundles_the_engine(tmp_path, paths):
    r = pip_install(tmp_path / "site")
    assert r.returncode == 0, r.stderr
    got = probe(tmp_path / "site")
    assert got.get("library", "").startswith(str(tmp_path / "site" / "ntscontact" / "_lib")), got
    # the bundled engine answers what the CLI of the build answers
    cli = subprocess.run([str(paths.cli), str(paths.examples / "two_disks.json")], capture_output=True, timeout=60)
    want = json.loads(cli.stdout)["summary"]
    assert (got["energy"], got["contacts"]) == (want["energy"], want["contacts"])


def test_pip_install_without_cmake_gives_the_http_client(tmp_path):
    r = pip_install(tmp_path / "site", NTSCONTACT_CMAKE=str(tmp_path / "no-cmake"))
    assert r.returncode == 0, r.stderr
    assert "installing without the in-process engine" in r.stdout + r.stderr  # shown with pip -v
    assert not (tmp_path / "site" / "ntscontact" / "_lib" / "libntscontact_engine.so").exists()
    got = probe(tmp_path / "site")
    assert "apt-get install" in got["unavailable"] and "NTSCONTACT_LIBRARY" in got["unavailable"]
    # and where the engine is required (the project's own install), no engine is a failure
    r = pip_install(tmp_path / "site2", NTSCONTACT_CMAKE=str(tmp_path / "no-cmake"), NTSCONTACT_REQUIRE_ENGINE="1")
    assert r.returncode != 0 and "could not be built" in r.stderr + r.stdout
