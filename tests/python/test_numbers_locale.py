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


def test_numbers_read_alike_in_a_decimal_comma_locale(tmp_path):
    localedef = shutil.which("localedef")
    assert localedef, "localedef (libc-bin) is missing"
    made = subprocess.run([localedef, "-i", "de_DE", "-f", "UTF-8", str(tmp_path / "de_DE.UTF-8")],
                          capture_output=True, text=True, timeout=120)
    if made.returncode > 1:  # (1: warnings only; the locale is written)
        pytest.fail(f"localedef could not build de_DE.UTF-8 (scripts/install-deps.sh installs `locales`): "
                    f"{made.stderr[-500:]}")
    binary = BUILD / "bin" / "test_numparse"
    assert binary.exists(), binary
    r = subprocess.run([str(binary)], capture_output=True, text=True, timeout=600,
                       env={"LOCPATH": str(tmp_path), "NTS_TEST_LOCALE": "de_DE.UTF-8", "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stdout[-2000:]
    assert "read alike in the locale de_DE.UTF-8 (decimal point ',')" in r.stdout, r.stdout[-2000:]
