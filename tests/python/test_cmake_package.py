"""`cmake --install` then `find_package(ntscontact)` from the install prefix:
a user's project (tests/cmake/consumer) configures, builds against the core
and the codec, and runs."""
import pathlib
import shutil
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_find_package_from_an_install_prefix(paths, tmp_path):
    config = (paths.build / "core" / "generated" / "ntscontact" / "config.h").read_text()
    if "NTS_CONFIG_SANITIZE 1" in config:
        pytest.skip("a sanitizer build: its static libraries need the sanitizer runtime in the consumer too")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(paths.build), "--prefix", str(prefix)], check=True,
                   capture_output=True, timeout=120)
    assert (prefix / "include" / "ntscontact" / "ntscontact.h").exists()
    assert (prefix / "include" / "ntscontact" / "config.h").exists()
    assert list(prefix.glob("lib*/cmake/ntscontact/ntscontactConfig.cmake"))
    build = tmp_path / "consumer"
    r = subprocess.run(["cmake", "-S", str(REPO / "tests" / "cmake" / "consumer"), "-B", str(build),
                        f"-DCMAKE_PREFIX_PATH={prefix}"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run(["cmake", "--build", str(build)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    out = subprocess.run([str(build / "consumer")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "version 0.2.0" in out.stdout and "contacts " in out.stdout and "codec has energy" in out.stdout
    assert int(out.stdout.split("contacts ")[1].split()[0]) > 0
