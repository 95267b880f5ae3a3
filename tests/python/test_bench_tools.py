"""The benchmark tools' own edges (bench/): they rewrite sections of the
docs, and a rewrite must leave what another program wrote."""
import os
import subprocess
import sys

import pytest

from conftest import BUILD, REPO

sys.path.insert(0, str(REPO / "bench" / "sessions"))
from common import replace_section  # noqa: E402


def test_replace_section_keeps_another_programs_subsection(tmp_path):
    """scale_out.py --write rewrites "Scale-out behind nginx", whose
    subsection "Many clients" another program writes: that one stays, the
    section's own subsection is replaced, a shell comment in a code block is
    no heading, and the next section stays."""
    doc = tmp_path / "b.md"
    doc.write_text("# T\n\n## A\n\nold a\n```sh\n# comment\n```\nmore old\n\n### Mine\n\nold mine\n\n"
                   "### Other\n\nother's\n\n## B\n\nb\n")
    replace_section(doc, "## A", "## A\n\nnew a\n\n### Mine\n\nnew mine\n")
    assert doc.read_text() == "# T\n\n## A\n\nnew a\n\n### Mine\n\nnew mine\n\n### Other\n\nother's\n\n## B\n\nb\n"


def test_replace_section_at_the_end_and_absent(tmp_path):
    doc = tmp_path / "b.md"
    doc.write_text("# T\n\n## A\n\nold\n")
    replace_section(doc, "## A", "## A\n\nnew\n")
    assert doc.read_text() == "# T\n\n## A\n\nnew\n"
    replace_section(doc, "## C", "## C\n\nc\n")
    assert doc.read_text() == "# T\n\n## A\n\nnew\n\n## C\n\nc\n"


def test_write_results_beside_a_doc_of_ones_own(tmp_path):
    """A session benchmark run with --out elsewhere writes its CSV beside
    that file, not over the committed bench/results/ one."""
    from common import write_results
    committed = REPO / "bench" / "results" / "sessions_test_only.csv"
    out = tmp_path / "mine.md"
    write_results([{"a": 1, "b": 2}], "sessions_test_only.csv", out, "## S", "## S\n\nbody\n")
    assert (tmp_path / "sessions_test_only.csv").read_text().splitlines() == ["a,b", "1,2"]
    assert not committed.exists()
    assert out.read_text() == "## S\n\nbody\n"


@pytest.mark.parametrize("args, fault", [(["x"], "rounds: a positive integer, not 'x'"),
                                         (["2", "0"], "steps: a positive integer, not '0'"),
                                         (["1", "2", "3"], "at most two arguments")])
def test_fortran_loop_bad_arguments(args, fault):
    """bench/fortran_loop: a bad command line names the fault and the usage
    on stderr, exit 2, and nothing else (no gfortran "STOP 2" line, no
    backtrace, no table started on stdout)."""
    prog = BUILD / "bin" / "fortran_loop"
    if not prog.exists():
        pytest.skip("built without gfortran")
    # (under the sanitizers, ASan's strict_string_checks reads libgfortran's
    # strndup of a format string, which is no C string, as an overflow)
    env = dict(os.environ, ASAN_OPTIONS=os.environ.get("ASAN_OPTIONS", "") + ":strict_string_checks=0")
    got = subprocess.run([str(prog), *args], capture_output=True, text=True, timeout=60, env=env)
    assert got.returncode == 2 and got.stdout == ""
    assert got.stderr.splitlines() == [f"fortran_loop: {fault}",
                                       "usage: fortran_loop [rounds [steps]]  (default 5 rounds of 40 steps)"]
