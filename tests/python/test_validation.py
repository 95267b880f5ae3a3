"""bench/validation (docs/validation.md): the quick suite against scikit-fem FEM models,
each bound of bench/validation/run.py's BOUNDS asserted on its own (Hertz a and p0 on a
disk and two disks, the penalty rule, the drag over a 24-gon at alpha 0 and 0.2, Newton and
FIRE converged). No timing is asserted."""
import sys

import pytest

pytest.importorskip("skfem")
pytest.importorskip("scipy")

from conftest import REPO, start_daemon  # noqa: E402

sys.path.insert(0, str(REPO / "bench" / "validation"))
import run as validation  # noqa: E402

from fem import service  # noqa: E402


@pytest.fixture(scope="module")
def figures(paths, tmp_path_factory):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("validation") / "daemon.log")
    try:
        with service(d.base) as client:
            f, _ = validation.quick(client)
    finally:
        d.stop()
    return f


@pytest.mark.parametrize("bound", validation.BOUNDS, ids=[b.key for b in validation.BOUNDS])
def test_bound(figures, bound):
    value = figures[bound.key]
    assert bound.test(value), f"{bound.key} = {value!r}: expected {bound.text} ({bound.why})"


def test_every_figure_has_a_bound_or_is_reported(figures):
    """The bounds name figures that exist (a renamed figure would otherwise never be checked)."""
    missing = [b.key for b in validation.BOUNDS if b.key not in figures]
    assert not missing, missing
