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


def exported(library):
    """The functions a shared library exports (nm -D --defined-only)."""
    out = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return {line.split()[-1] for line in out.stdout.splitlines() if " T " in line}


def test_the_checkouts_engine_is_the_builds():
    """In a checkout whose package is an editable install (install-deps.sh
    makes one), Engine() loads the package's own copy of the library, built
    once by pip: scripts/build.sh (which test.sh and demo.sh run) brings it
    up to date, so that it exports what the build's library exports. It was
    left as first built: after a pull, Engine(max_bytes=...) said the library
    predated it."""
    from conftest import BUILD
    from ntscontact.engine import LIBRARY_NAME, locate

    bundled = REPO / "clients" / "python" / "src" / "ntscontact" / "_lib" / LIBRARY_NAME
    if os.environ.get("NTSCONTACT_LIBRARY") or locate("NTSCONTACT_LIBRARY", LIBRARY_NAME) != bundled:
        pytest.skip("the package here is not this checkout's editable install")
    built = BUILD / "lib" / LIBRARY_NAME
    assert built.is_file(), built
    assert exported(bundled) == exported(built)
