"""bench/validation (docs/validation.md): the quick suite against scikit-fem FEM models,
each bound of bench/validation/run.py's BOUNDS asserted on its own (Hertz a and p0 on a
disk and two disks, the penalty rule, the drag over a 24-gon at alpha 0 and 0.2, Newton and
FIRE converged, the patch test, Cattaneo-Mindlin with Coulomb friction). No timing is asserted."""
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


def test_boundary_segments_run_counter_clockwise():
    """fem.boundary_segments (the patch test's contact surfaces, docs/validation.md §4):
    a 2 x 1 block's boundary edges with the body to their left, and the top selected."""
    import numpy as np

    from fem import block_mesh, boundary_segments

    m = block_mesh(0.0, 0.0, 2.0, 1.0, 2, 1)
    p = m.p.T
    segs = boundary_segments(m)
    assert len(segs) == 6
    for i, j in segs:   # the outward normal (t_y, -t_x) points away from the centre (1, 0.5)
        t, mid = p[j] - p[i], 0.5 * (p[i] + p[j])
        assert np.dot([t[1], -t[0]], mid - [1.0, 0.5]) > 0
    top = boundary_segments(m, lambda x, y: np.isclose(y, 1.0))
    assert sorted(map(tuple, p[top][:, :, 0].tolist())) == [(1.0, 0.0), (2.0, 1.0)]
