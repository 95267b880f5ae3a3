"""The Python client's surface exchange (`client.session(scene,
exchange="surface")`, docs/sessions.md): the session knows the surface nodes,
its binary steps send and receive their rows alone, and every result equals
the one of a session exchanging every node, bit for bit (forces with zeros
inside, pressures, the tangent, the summary); contacts and gaps still come
whole in JSON; the in-process engine does the same."""
import contextlib
import json
import os

import numpy as np
import pytest

from conftest import BUILD, positions_of

ntscontact = pytest.importorskip("ntscontact")
from ntscontact import Client, Engine  # noqa: E402

from test_surface_exchange import boundary_nodes, grid_mesh_and_disk  # noqa: E402

LIBRARY = BUILD / "lib" / "libntscontact_engine.so"


def need_engine():
    """The build's engine library, loaded into this Python: not a sanitized
    one (scripts/test-sanitize.sh), which cannot be (test_engine.py)."""
    if os.environ.get("NTS_SANITIZED") == "1":
        pytest.skip("a sanitized library cannot be loaded into an uninstrumented Python")
    if not LIBRARY.is_file():
        pytest.fail(f"{LIBRARY} is not built (NTS_BUILD_DIR={BUILD})")


@pytest.fixture
def client(daemon):
    with Client(daemon.base, timeout=60) as c:
        yield c


def scenes(paths):
    return [json.loads((paths.examples / "triangle_meshes.json").read_text()), grid_mesh_and_disk(10)]


def same(a, b):
    assert np.array_equal(a.force_array(), b.force_array())
    assert a.summary.contacts == b.summary.contacts and a.summary.energy == b.summary.energy
    assert np.array_equal(a.summary.virial, b.summary.virial)
    assert a.summary.max_penetration == b.summary.max_penetration and a.summary.gaps == b.summary.gaps


def walk(opener, scene):
    """Steps of two sessions, one exchanging the surface, at the same random positions."""
    pos0 = positions_of(scene)
    rng = np.random.default_rng(3)
    scale = 0.003 * np.ptp(pos0, axis=0).max()
    with opener(scene, exchange="surface") as s, opener(scene) as t:
        assert s.surface is not None and t.surface is None
        assert s.surface.tolist() == boundary_nodes(scene) and len(s.surface) < s.nodes
        active = 0
        for k in range(6):
            pos = pos0 + scale * rng.standard_normal(pos0.shape)
            outs = ["forces", "energy", "virial", "stiffness", "pressure"]
            a, b = s.contact(pos, outputs=outs), t.contact(pos, outputs=outs)
            same(a, b)
            f = a.force_array()
            assert f.shape == pos.shape and not f.flags.writeable
            assert not np.any(np.delete(f, s.surface, axis=0))
            for body in a.forces:  # per body, as the whole answer gives it
                assert np.array_equal(a.forces[body], b.forces[body])
                assert np.array_equal(a.pressure[body], b.pressure[body])
            ta, tb = a.stiffness, b.stiffness
            assert (ta != tb).nnz == 0 and ta.shape == tb.shape == (2 * s.nodes, 2 * s.nodes)
            active += a.summary.contacts
            # at the stored positions, and with contacts asked (a JSON answer, every node)
            same(s.contact(), t.contact())
            ja, jb = s.contact(pos, outputs=["forces", "contacts"]), t.contact(pos, outputs=["forces", "contacts"])
            same(ja, jb)
            assert ja.contacts == jb.contacts
        assert active > 0
        assert np.array_equal(s.positions(), t.positions())


def test_surface_sessions_answer_as_whole_ones(client, paths):
    for scene in scenes(paths):
        walk(client.session, scene)
    with pytest.raises(ValueError):
        client.session(scenes(paths)[0], exchange="boundary")


def test_engine_surface_sessions_answer_as_whole_ones(paths):
    need_engine()
    with Engine(library=LIBRARY) as e:
        for scene in scenes(paths):
            walk(e.session, scene)


def test_surface_sessions_store_what_the_service_holds_and_recreate(client, daemon, paths, tmp_path):
    """A surface step stores the surface rows it sent, the other nodes as they
    were (what the service holds); a session the service lost is created
    again (its surface asked anew) and the step answered as before."""
    import requests

    scene = grid_mesh_and_disk(10)
    pos0 = positions_of(scene)
    p1 = pos0 + 0.003
    p1[-24:, 1] -= 0.01  # the disk a little deeper
    with client.session(scene, exchange="surface") as s, client.session(scene) as t:
        r1 = s.contact(p1)
        stored = pos0.copy()
        stored[s.surface] = p1[s.surface]
        assert np.array_equal(s.positions(), stored)
        want = t.contact(stored)
        same(r1, want)
        assert r1.summary.contacts > 0
        p2 = p1 + 0.001
        r2 = s.contact(p2)  # the rows of this step replace those of the last
        stored[s.surface] = p2[s.surface]
        assert np.array_equal(s.positions(), stored)
        w2 = t.contact(stored)
        same(r2, w2)
        # the result knows its positions (the stored ones): the same picture
        r2.to_vtk(tmp_path / "surface.vtu")
        w2.to_vtk(tmp_path / "whole.vtu")
        assert (tmp_path / "surface.vtu").read_bytes() == (tmp_path / "whole.vtu").read_bytes()
        # lost behind the client's back: the stored surface rows sent to the new session
        first = s.id
        assert requests.delete(daemon.url(f"/v1/scenes/{first}"), timeout=10).status_code == 204
        again = s.contact()
        assert s.recreated == 1 and s.id != first and s.surface.tolist() == boundary_nodes(scene)
        same(again, r2)
        assert requests.delete(daemon.url(f"/v1/scenes/{s.id}"), timeout=10).status_code == 204
        p3 = p2 - 0.002
        again = s.contact(p3)
        stored[s.surface] = p3[s.surface]
        assert s.recreated == 2
        same(again, t.contact(stored))
        assert np.array_equal(s.positions(), stored)


def test_surface_then_whole_steps_store_the_last_sent(client, paths):
    """A whole step after surface steps stores every node it sent; a
    surface step after it, its rows over those; a result's picture is drawn
    at the positions it was evaluated at."""
    import matplotlib

    matplotlib.use("Agg")
    from ntscontact.plot import plot

    scene = grid_mesh_and_disk(10)
    pos0 = positions_of(scene)
    with client.session(scene, exchange="surface") as s:
        r1 = s.contact(pos0 + 0.001)
        p2 = pos0 - 0.002
        s.contact(p2, outputs=["forces", "contacts"])  # a JSON answer: every node sent
        assert np.array_equal(s.positions(), p2)
        p3 = pos0 + 0.003
        r3 = s.contact(p3)
        want = p2.copy()
        want[s.surface] = p3[s.surface]
        assert np.array_equal(s.positions(), want)
        assert np.array_equal(r3._positions(), want)
        first = pos0.copy()
        first[s.surface] = pos0[s.surface] + 0.001
        assert np.array_equal(r1._positions(), first)
        ax = plot(ntscontact.Scene.from_dict(scene), r3)
        drawn = np.concatenate([np.asarray(line.get_xydata()) for line in ax.lines])
        assert np.isin(drawn[:, 0], want[:, 0]).any()


def test_engine_a_surface_step_after_a_refused_whole_one(paths):
    """A whole step refused for a NaN inside the mesh, its positions copied
    (an unaligned array) before the check: a surface step after it that
    makes the scene anew (the mesh mirrored) takes the stored positions of
    the nodes it does not send, as a whole session given them does."""
    need_engine()
    from ntscontact import InvalidScene
    from test_engine import unaligned
    scene = grid_mesh_and_disk(10)
    pos0 = positions_of(scene)
    with Engine(library=LIBRARY) as e, e.session(scene, exchange="surface") as s, e.session(scene) as t:
        inside = np.setdiff1d(np.arange(len(pos0)), s.surface)
        bad = pos0.copy()
        bad[inside[3], 0] = np.nan
        with pytest.raises(InvalidScene) as err:
            s.contact(unaligned(bad), outputs=["forces", "contacts"])  # every node sent, refused
        assert err.value.code == "non_finite" and err.value.pointer == f"/positions/{inside[3]}"
        mirrored = pos0.copy()
        mirrored[s.surface, 0] = 2.0 - mirrored[s.surface, 0]
        for pos in (mirrored, pos0):
            whole = pos0.copy()
            whole[s.surface] = pos[s.surface]
            same(s.contact(pos), t.contact(whole))


@pytest.mark.parametrize("backend", ["client", "engine"])
def test_a_refused_surface_step_points_at_the_callers_row(client, paths, backend):
    """A NaN in a surface node's row of the caller's array, sent as one of
    the surface rows alone: the error's pointer is /positions/<row> of the
    caller's array (docs/python.md), as the whole exchange's is, not the
    index among the rows sent."""
    if backend == "engine":
        need_engine()
    scene = grid_mesh_and_disk(10)
    pos0 = positions_of(scene)
    with (Engine(library=LIBRARY) if backend == "engine" else contextlib.nullcontext(client)) as opener, \
            opener.session(scene, exchange="surface") as s, opener.session(scene) as t:
        k = len(s.surface) - 1
        row = int(s.surface[k])
        assert row != k  # (interior nodes come before it)
        bad = pos0.copy()
        bad[row, 1] = np.inf
        errors = []
        for session in (s, t):
            with pytest.raises(ntscontact.InvalidScene) as err:
                session.contact(bad, outputs=["forces"])
            errors.append(err.value)
        assert [(e.code, e.pointer) for e in errors] == [("non_finite", f"/positions/{row}")] * 2
        assert f"/positions/{row}" in str(errors[0]) and f"/positions/{k})" not in str(errors[0])
        same(s.contact(pos0), t.contact(pos0))  # the stored positions unchanged
