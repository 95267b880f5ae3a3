"""A JSON number means the same whatever locale the host process set: the
codec runs inside other programs (the Python engine, a Fortran or C
solver), and a program that calls setlocale with a decimal comma made the
numbers the codec leaves to strtod (more than 19 digits, |exponent| > 27,
64 characters or more) read wrong: "1.5e30" as 1. test_numparse, run in a
German locale built here with localedef (the `locales` package,
scripts/install-deps.sh), reads them as the C locale does."""
import shutil
import subprocess

import pytest

from conftest import BUILD


def make_locale(where):
    """de_DE.UTF-8 (a decimal comma) built into `where`, for LOCPATH."""
    localedef = shutil.which("localedef")
    assert localedef, "localedef (libc-bin) is missing"
    made = subprocess.run([localedef, "-i", "de_DE", "-f", "UTF-8", str(where / "de_DE.UTF-8")],
                          capture_output=True, text=True, timeout=120)
    if made.returncode > 1:  # (1: warnings only; the locale is written)
        pytest.fail(f"localedef could not build de_DE.UTF-8 (scripts/install-deps.sh installs `locales`): "
                    f"{made.stderr[-500:]}")


def test_numbers_read_alike_in_a_decimal_comma_locale(tmp_path):
    make_locale(tmp_path)
    binary = BUILD / "bin" / "test_numparse"
    assert binary.exists(), binary
    r = subprocess.run([str(binary)], capture_output=True, text=True, timeout=600,
                       env={"LOCPATH": str(tmp_path), "NTS_TEST_LOCALE": "de_DE.UTF-8", "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stdout[-2000:]
    assert "read alike in the locale de_DE.UTF-8 (decimal point ',')" in r.stdout, r.stdout[-2000:]


ENGINE_IN_A_LOCALE = """
import json, locale, sys
import ntscontact
scene = open(sys.argv[1]).read()
eng = ntscontact.Engine()
before = json.loads(eng.contact_json(scene))
locale.setlocale(locale.LC_ALL, "de_DE.UTF-8")
assert locale.localeconv()["decimal_point"] == ","
after = json.loads(eng.contact_json(scene))
for r in (before, after):
    r["summary"].pop("elapsed_ms")
print("same" if before == after else "differ")
"""


def test_the_engine_in_process_answers_alike_in_a_decimal_comma_locale(tmp_path, paths):
    """The in-process engine (the codec in a Python program that set a
    decimal-comma locale) answers as before the locale was set, bit for bit:
    the bundled packing as it is, and with every real written with 25
    digits. A scene document goes through cJSON (which reads with the
    locale's decimal point swapped in) and the answer through the codec's
    printer (no locale at all); the test above holds the codec's own reader
    to the same."""
    import os
    import re
    import sys
    make_locale(tmp_path)
    text = (paths.examples / "jittered_packing.json").read_text()
    wide = re.sub(r"(?<![\w.])(-?\d+\.\d+(?:[eE][-+]?\d+)?)", lambda m: "%.24e" % float(m.group(1)), text)
    assert wide != text and "e-" in wide
    (tmp_path / "wide.json").write_text(wide)
    env = dict(os.environ, LOCPATH=str(tmp_path))
    for scene in (paths.examples / "jittered_packing.json", tmp_path / "wide.json"):
        r = subprocess.run([sys.executable, "-c", ENGINE_IN_A_LOCALE, str(scene)], capture_output=True, text=True,
                           env=env, timeout=300)
        assert r.returncode == 0 and r.stdout.strip() == "same", (scene.name, r.stdout, r.stderr[-2000:])
