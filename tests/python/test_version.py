"""One version, written in VERSION: every copy agrees with it (scripts/version.py),
and every front end prints it."""
import importlib.util
import shutil
import subprocess
import sys

from conftest import REPO

VERSION = (REPO / "VERSION").read_text().strip()


def load_script():
    spec = importlib.util.spec_from_file_location("version_script", REPO / "scripts" / "version.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_copy_equals_VERSION():
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "version.py")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == VERSION


def test_a_copy_that_differs_is_found(tmp_path, monkeypatch):
    mod = load_script()
    for path, _ in mod.COPIES:
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / path, tmp_path / path)
    (tmp_path / "VERSION").write_text(VERSION + "\n")
    monkeypatch.setattr(mod, "REPO", tmp_path)
    assert mod.check(VERSION) == []
    init = tmp_path / "clients/python/src/ntscontact/__init__.py"
    init.write_text(init.read_text().replace(f'"{VERSION}"', '"9.9.9"'))
    bad = mod.check(VERSION)
    assert len(bad) == 1 and "__init__.py: 9.9.9" in bad[0]
    # writing a new version writes every copy, and then they agree again
    mod.write("1.2.3")
    assert mod.read_version() == "1.2.3" and mod.check("1.2.3") == []


def test_every_front_end_prints_it(paths):
    outs = [subprocess.run(cmd, capture_output=True, text=True, timeout=30).stdout.split()
            for cmd in ([str(paths.cli), "--version"], [str(paths.bin / "ntscontactd"), "--version"],
                        [sys.executable, "-m", "ntscontact", "--version"])]
    assert outs[0] == ["ntscontact", VERSION]
    assert outs[1][:2] == ["ntscontactd", VERSION]
    assert outs[2][:2] == ["ntscontact-python", VERSION]
