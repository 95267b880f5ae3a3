"""The in-process engine (`ntscontact.Engine`) against the daemon: the same
bytes for every bundled example and for random scenes (valid and not), the same
session steps (binary and JSON, with friction's commit), the same errors, the
forces as a view of the library's answer, and concurrent use.

The library under test is the build's (`$NTS_BUILD_DIR/lib`), the one the
daemon beside it was built with; tests/python/test_packaging.py checks the copy
`pip install` bundles."""
import json
import math
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from conftest import BUILD, positions_of, with_positions
import requests

if os.environ.get("NTS_SANITIZED") == "1":  # scripts/test-sanitize.sh
    pytest.skip("a sanitized library cannot be loaded into an uninstrumented Python; ctest's `engine` "
                "(tests/codec/test_engine.c) runs the engine's calls under the sanitizers", allow_module_level=True)

ntscontact = pytest.importorskip("ntscontact")
from ntscontact import Client, Engine, EngineSession, EngineUnavailable, InvalidScene  # noqa: E402

LIBRARY = BUILD / "lib" / "libntscontact_engine.so"
EXAMPLES = ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"]
JSON = {"Content-Type": "application/json"}
ALL_OUTPUTS = ["forces", "energy", "virial", "contacts", "gaps", "stiffness", "pressure"]


@pytest.fixture(scope="module")
def engine():
    if not LIBRARY.is_file():
        pytest.fail(f"{LIBRARY} is not built (NTS_BUILD_DIR={BUILD})")
    with Engine(library=LIBRARY) as e:
        yield e


@pytest.fixture
def client(daemon):
    with Client(daemon.base, timeout=60) as c:
        yield c


def load(paths, name):
    return json.loads((paths.examples / f"{name}.json").read_text())


def daemon_text(daemon, doc):
    r = requests.post(daemon.url("/v1/contact"), data=json.dumps(doc), timeout=60, headers=JSON)
    return r.status_code, r.content


def same_bytes_but_elapsed(a, b):
    """The same text byte for byte, the summary's elapsed_ms cut out of both."""
    cut = [re.sub(rb'"elapsed_ms": ?[-0-9.eE+]+', b'"elapsed_ms":_', t) for t in (a, b)]
    assert cut[0].count(b'"elapsed_ms":_') == (1 if b'"summary"' in a else 0)
    assert cut[0] == cut[1]


def polygon(n, r, c, phase):
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t)], axis=1)


def random_scene(rng):
    """A packing of polygons with random options: what the daemon's tests throw
    at it, each output and option switched on somewhere."""
    count = int(rng.integers(2, 7))
    bodies = []
    for k in range(count):
        n = int(rng.integers(3, 40))
        r = float(rng.uniform(0.5, 1.5))
        c = rng.uniform(0, 4, size=2)
        body = {"id": f"b{k}" if rng.random() < 0.7 else k, "nodes": polygon(n, r, c, rng.uniform(0, 6)).tolist()}
        if rng.random() < 0.2:
            body["alpha"] = float(rng.choice([0.0, 0.1, 0.4]))
        if rng.random() < 0.15:
            body["friction"] = float(rng.uniform(0, 0.8))
        bodies.append(body)
    options = {"penalty": float(rng.uniform(10, 1e4)), "alpha": float(rng.choice([0.0, 0.1, 0.2, 0.5])),
               "search_radius": float(rng.uniform(0.05, 0.6)),
               "outputs": [o for o in ALL_OUTPUTS if rng.random() < 0.6] or ["forces"]}
    if rng.random() < 0.3:
        options["solver"] = str(rng.choice(["closed_form", "newton"]))
    if rng.random() < 0.25:
        options["periodic"] = {"lx": 5.0, "ly": 5.0}
    if rng.random() < 0.25:
        options["friction"] = {"coefficient": float(rng.uniform(0.1, 0.6))}
    doc = {"options": options, "bodies": bodies}
    if rng.random() < 0.15:  # an invalid one: the same error document
        fault = int(rng.integers(0, 4))
        if fault == 0:
            options["penalty"] = -1.0
        elif fault == 1:
            bodies[0]["nodes"][1] = bodies[0]["nodes"][0]
        elif fault == 2:
            options["outputs"] = ["forces", "nothing"]
        else:
            bodies[-1]["nodes"] = bodies[-1]["nodes"][:2]
    return doc


# ------------------------------------------------------------ stateless

@pytest.mark.parametrize("name", EXAMPLES)
def test_examples_answer_the_daemons_bytes(engine, daemon, paths, name):
    doc = load(paths, name)
    for outputs in (None, ALL_OUTPUTS):
        d = dict(doc, options=dict(doc["options"], outputs=outputs)) if outputs else doc
        status, want = daemon_text(daemon, d)
        assert status == 200
        got = engine.contact_json(d)
        same_bytes_but_elapsed(got, want)
    # and as a Result: the Client's, field by field
    r_e = engine.contact(doc, outputs=ALL_OUTPUTS)
    with Client(daemon.base, timeout=60) as c:
        r_c = c.contact(doc, outputs=ALL_OUTPUTS)
    assert np.array_equal(r_e.force_array(), r_c.force_array())
    assert r_e.contacts == r_c.contacts and r_e.gaps == r_c.gaps
    assert (r_e.stiffness != r_c.stiffness).nnz == 0


def test_random_scenes_answer_the_daemons_bytes(engine, daemon):
    rng = np.random.default_rng(28)
    errors = 0
    for _ in range(60):
        doc = random_scene(rng)
        status, want = daemon_text(daemon, doc)
        if status == 200:
            same_bytes_but_elapsed(engine.contact_json(doc), want)
            continue
        errors += 1
        err = json.loads(want)["error"]
        with pytest.raises(ntscontact.NtsError) as info:
            engine.contact(doc)
        assert (info.value.status, info.value.code, info.value.pointer) == (status, err["code"], err["pointer"])
        assert info.value.message == err["message"]
    assert errors >= 3  # the invalid ones were exercised


def test_validate_and_bad_json(engine, daemon, paths):
    doc = load(paths, "two_disks")
    r = requests.post(daemon.url("/v1/validate"), data=json.dumps(doc), timeout=60, headers=JSON)
    got, want = engine.validate(doc), r.json()
    assert got["summary"].pop("elapsed_ms") >= 0 and want["summary"].pop("elapsed_ms") >= 0
    assert got == want and got["valid"] is True
    with pytest.raises(InvalidScene) as info:
        engine.contact('{"options": {"penalty": 1}, "bodies": [')
    assert info.value.code == "invalid_json" and info.value.status == 400


@pytest.mark.parametrize("backend", ["engine", "client"])
def test_scene_text_that_is_not_a_scene_is_refused_alike_on_every_path(engine, client, backend):
    """JSON text that does not parse, or is not an object: sent as it is (no
    outputs=, no history=) the service refuses it; read by the client (to add
    outputs or history, or to hold it in a session) the same InvalidScene,
    code and pointer, saying where (line, column): it was a bare
    json.JSONDecodeError, TypeError or AttributeError."""
    opener = engine if backend == "engine" else client
    calls = [lambda t: opener.contact(t), lambda t: opener.validate(t),
             lambda t: opener.contact(t, outputs=["forces"]), lambda t: opener.contact(t, history=[]),
             lambda t: opener.session(t), lambda t: opener.session(t.encode(), exchange="surface")]
    for text, code, says in (('{"version": 1,', "invalid_json", "line 1, column 15"),
                             ('{"version": 1}\n  x', "invalid_json", "line 2, column 3"),
                             ("[1, 2]", "invalid_type", "expected a scene (an object), got an array")):
        for call in calls:
            with pytest.raises(InvalidScene) as info:
                call(text)
            assert (info.value.code, info.value.pointer) == (code, ""), (text, str(info.value))
            assert says in info.value.message, (text, str(info.value))


@pytest.mark.parametrize("backend", ["engine", "client"])
def test_a_non_finite_number_in_a_dict_scene_is_named_where_it_is(engine, client, backend, paths):
    """A dict scene with an infinity or a NaN (JSON has neither): every path
    (sent with or without outputs=, with history=, held in a session) is the
    service's non_finite at the number's pointer, as the service says for
    text whose number overflows; it was json's bare ValueError."""
    opener = engine if backend == "engine" else client
    calls = [lambda d: opener.contact(d), lambda d: opener.contact(d, outputs=["forces"]),
             lambda d: opener.contact(d, history=[]), lambda d: opener.session(d), lambda d: opener.validate(d)]
    for where, value in ((("bodies", 1, "nodes", 3, 1), math.inf), (("options", "penalty"), math.nan),
                         (("bodies", 0, "nodes", 0, 0), -math.inf)):
        doc = load(paths, "two_disks")
        doc.setdefault("options", {})
        at = doc
        for key in where[:-1]:
            at = at[key]
        at[where[-1]] = value
        pointer = "/" + "/".join(map(str, where))
        for call in calls:
            with pytest.raises(InvalidScene) as info:
                call(doc)
            assert (info.value.code, info.value.pointer) == ("non_finite", pointer), str(info.value)
    doc = load(paths, "two_disks")
    doc["bodies"][1]["nodes"][3][1] = 12345.5
    text = json.dumps(doc).replace("12345.5", "1e999")
    with pytest.raises(InvalidScene) as info:  # the service's own words for text, the same code and place
        opener.contact(text)
    assert (info.value.code, info.value.pointer) == ("non_finite", "/bodies/1/nodes/3/1"), str(info.value)


@pytest.mark.parametrize("backend", ["engine", "client"])
def test_a_key_json_cannot_write_is_named_where_it_is(engine, client, backend, paths):
    """A dict scene with a key json.dumps cannot write (a tuple, a numpy
    integer): InvalidScene invalid_type at the object that holds it, on
    every path; it was json's bare TypeError."""
    opener = engine if backend == "engine" else client
    for key, code in (((1, 2), "invalid_type"), (np.int64(3), "invalid_type"), (math.nan, "non_finite"),
                      (-math.inf, "non_finite")):
        doc = load(paths, "two_disks")
        doc["bodies"][1][key] = 1
        for call in (lambda d: opener.contact(d, outputs=["forces"]), lambda d: opener.session(d)):
            with pytest.raises(InvalidScene) as info:
                call(doc)
            assert (info.value.code, info.value.pointer) == (code, "/bodies/1"), str(info.value)
            assert code == "non_finite" or type(key).__name__ in info.value.message


# ------------------------------------------------------------ sessions

def walk(scene, steps, seed, scale=3e-4):
    pos0 = positions_of(scene)
    rng = np.random.default_rng(seed)
    span = float(np.ptp(pos0[:, 0])) * scale
    for _ in range(steps):
        yield pos0 + rng.normal(scale=span, size=pos0.shape)


@pytest.mark.parametrize("name", EXAMPLES)
def test_session_steps_equal_the_daemons(engine, client, paths, name):
    scene = load(paths, name)
    with engine.session(scene) as es, client.session(scene) as hs:
        assert isinstance(es, EngineSession) and es.nodes == hs.nodes
        assert es.surface_nodes == hs.surface_nodes
        for k, pos in enumerate(walk(scene, 6, len(name))):
            outs = ["forces", "energy", "virial", "stiffness"] if k % 3 else ["forces", "contacts", "gaps"]
            got, want = es.contact(pos, outputs=outs), hs.contact(pos, outputs=outs)
            f = got.force_array()
            assert np.array_equal(f.view(np.uint64), want.force_array().view(np.uint64))
            assert got.summary.energy == want.summary.energy
            assert np.array_equal(got.summary.virial, want.summary.virial)
            assert got.summary.contacts == want.summary.contacts and got.contacts == want.contacts
            if "stiffness" in outs:
                assert (got.stiffness != want.stiffness).nnz == 0
            # and the stateless call at those positions
            full = engine.contact(with_positions(scene, pos), outputs=outs)
            assert np.array_equal(full.force_array(), f)
        # a step at the stored positions, and with options of its own
        got, want = es.contact(alpha=0.05, penalty=321.0), hs.contact(alpha=0.05, penalty=321.0)
        assert np.array_equal(got.force_array(), want.force_array())
        assert es.info()["steps"] == 7 and es.steps == 7


def test_friction_trials_and_commits_equal_the_daemons(engine, client, paths):
    scene = load(paths, "jittered_packing")
    scene["options"]["friction"] = {"coefficient": 0.4}
    with engine.session(scene) as es, client.session(scene) as hs:
        for k, pos in enumerate(walk(scene, 6, 9, scale=4e-4)):
            commit = k % 2 == 1
            got = es.step(pos, commit=commit, outputs=["forces", "energy", "virial"])
            want = hs.step(pos, commit=commit, outputs=["forces", "energy", "virial"])
            assert np.array_equal(got.force_array(), want.force_array())
            assert got.summary.dissipation == want.summary.dissipation
            assert (got.summary.sticking, got.summary.slipping) == (want.summary.sticking, want.summary.slipping)
            assert np.array_equal(got.summary.virial, want.summary.virial)


def test_forces_are_a_read_only_view_of_the_answer(engine, paths):
    scene = load(paths, "two_disks")
    with engine.session(scene) as s:
        pos = positions_of(scene)
        binary = ["forces", "energy", "virial"]
        f = s.contact(pos, outputs=binary).force_array()
        assert not f.flags.owndata and not f.flags.writeable
        want = engine.contact(with_positions(scene, pos)).force_array()
        g = s.contact(pos + 1e-4, outputs=binary).force_array()  # the next answer does not overwrite this one
        assert np.array_equal(f, want) and not np.array_equal(f, g)
    assert np.array_equal(f, want)  # the view outlives its session


def unaligned(arr):
    """A copy of float64 array `arr` one byte past an 8-byte boundary."""
    raw = np.zeros(arr.nbytes + 9, dtype=np.uint8)
    start = (1 - raw.ctypes.data) % 8
    out = np.frombuffer(raw.data, dtype="<f8", count=arr.size, offset=start).reshape(arr.shape)
    out[...] = arr
    assert out.ctypes.data % 8 != 0 and not out.flags.aligned
    return out


def test_positions_read_in_place_or_copied_give_the_same_answers(engine, paths):
    """A step's positions are read where they lie when they are aligned
    little-endian doubles (the daemon's request body, a numpy array), else
    copied first: the same answers, the same faults."""
    scene = load(paths, "jittered_packing")
    with engine.session(scene) as es, engine.session(scene) as us:
        for k, pos in enumerate(walk(scene, 4, 17)):
            outs = ["forces", "energy", "virial"] if k % 2 else ["forces", "contacts"]
            got, want = us.contact(unaligned(pos), outputs=outs), es.contact(pos, outputs=outs)
            assert np.array_equal(got.force_array().view(np.uint64), want.force_array().view(np.uint64))
            assert got.summary.energy == want.summary.energy and got.contacts == want.contacts
        for value in (np.nan, np.inf):
            bad = pos.copy()
            bad[7, 1] = value
            faults = []
            for s, arr in ((es, bad), (us, unaligned(bad))):
                with pytest.raises(InvalidScene) as info:
                    s.contact(arr)
                faults.append((info.value.code, info.value.pointer, info.value.message))
            assert faults[0] == faults[1] and faults[0][:2] == ("non_finite", "/positions/7"), faults
        # a refused step keeps the stored positions (in place: the request's bytes are not kept)
        got, want = us.contact(outputs=["forces"]), es.contact(outputs=["forces"])
        assert np.array_equal(got.force_array(), want.force_array())
        assert np.array_equal(got.force_array(), engine.contact(with_positions(scene, pos)).force_array())


def test_session_errors_are_the_daemons(engine, client, paths):
    scene = load(paths, "two_disks")
    with engine.session(scene) as es, client.session(scene) as hs:
        pos = positions_of(scene)
        for kw in ({"alpha": -1.0}, {"solver": "magic"}, {"outputs": "forces,nothing"}):
            with pytest.raises(InvalidScene) as e_info:
                es.contact(pos, **kw)
            with pytest.raises(InvalidScene) as h_info:
                hs.contact(pos, **kw)
            assert (e_info.value.code, e_info.value.pointer, e_info.value.message) == \
                   (h_info.value.code, h_info.value.pointer, h_info.value.message)
        bad = pos.copy()
        bad[5] = bad[4]  # a zero-length segment
        with pytest.raises(InvalidScene) as e_info:
            es.contact(bad)
        with pytest.raises(InvalidScene) as h_info:
            hs.contact(bad)
        assert (e_info.value.code, e_info.value.pointer) == (h_info.value.code, h_info.value.pointer)
        # the session goes on after a failed step
        assert np.array_equal(es.contact(pos).force_array(), hs.contact(pos).force_array())
    with pytest.raises(ntscontact.NtsError):
        es.contact(pos)  # closed
    with pytest.raises(InvalidScene):
        engine.session({"options": {"penalty": -1}, "bodies": scene["bodies"]})


def test_concurrent_steps_and_calls_give_each_its_own_answer(engine, paths):
    scene = load(paths, "jittered_packing")
    moves = list(walk(scene, 8, 3))
    want = [engine.contact(with_positions(scene, p)).force_array() for p in moves]
    got = {}
    with engine.session(scene) as s:
        def work(i):
            for k in range(i, len(moves), 4):
                got[k] = (s.contact(moves[k]).force_array(), engine.contact(with_positions(scene, moves[k])))
        threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    for k, w in enumerate(want):
        assert np.array_equal(got[k][0], w) and np.array_equal(got[k][1].force_array(), w)


@pytest.mark.parametrize("exchange", ["all", "surface"])
@pytest.mark.parametrize("backend", ["engine", "client"])
def test_stored_positions_are_the_last_step_accepted(engine, client, paths, backend, exchange, monkeypatch):
    """Two threads step one session at once, round after round: afterwards
    the client's stored positions (s.positions()) are those the library or
    the daemon holds, i.e. a step without positions answers what a step at
    s.positions() does. The client's update of its copy once a step is
    answered is delayed by a random fraction of a millisecond, so that the
    other thread's step often lands between the two: the session's lock
    must cover the call and the update. (They were updated outside it:
    12 to 18 rounds in 40 disagreed, and without the delay 1 round in 5
    to 1 in 300, by exchange and machine.)"""
    scene = load(paths, "two_disks")
    pos0 = positions_of(scene)
    moved = []
    for k in (1, 2):  # the right disk pushed in, by two depths: different forces
        x = pos0.copy()
        x[48:, 0] -= 0.01 * k
        moved.append(x)
    want = [engine.contact(with_positions(scene, x), outputs=["forces"]).force_array() for x in moved]
    assert not np.array_equal(want[0], want[1])
    rng = np.random.default_rng(11)
    s = (engine if backend == "engine" else client).session(scene, exchange=exchange)
    post = s._post_step

    def answered_late(*args, **kw):
        out = post(*args, **kw)
        time.sleep(float(rng.uniform(0, 1e-3)))
        return out

    monkeypatch.setattr(s, "_post_step", answered_late)
    disagree = 0
    with s:
        for _ in range(40):
            barrier = threading.Barrier(2)

            def step(x):
                barrier.wait()
                s.contact(x, outputs=["forces"])

            threads = [threading.Thread(target=step, args=(x,)) for x in moved]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            stored = s.positions()
            k = 0 if np.array_equal(stored, moved[0]) else 1
            assert np.array_equal(stored, moved[k])
            held = s.contact(outputs=["forces"]).force_array()  # at the positions the session holds
            disagree += not np.array_equal(held, want[k])
    assert disagree == 0


def test_threads_do_not_change_the_bits(paths):
    scene = load(paths, "periodic_packing")
    with Engine(threads=1, library=LIBRARY) as one, Engine(threads=3, library=LIBRARY) as three:
        a = one.contact_json(scene, ALL_OUTPUTS)
        b = three.contact_json(scene, ALL_OUTPUTS)
    same_bytes_but_elapsed(a, b)


FORKED = r"""
import ctypes, json, os, re, signal, sys
from ntscontact import Engine
library, scene, other = sys.argv[1], json.loads(open(sys.argv[2]).read()), sys.argv[3]
outputs = ["forces", "energy", "virial", "contacts", "stiffness"]
def cut(text):
    return re.sub(rb'"elapsed_ms": ?[-0-9.eE+]+', b"", text)
with Engine(threads=2, library=library) as e:
    if other:  # OpenMP's threads started by other code; the engine has not evaluated
        assert ctypes.CDLL(other).other_parallel() == 2
        before = cut(Engine(threads=0, library=library).contact_json(scene, outputs))
    else:
        before = cut(e.contact_json(scene, outputs))
    pid = os.fork()
    if pid == 0:  # the child: the parent's engine and a new one, each with two threads
        signal.alarm(120)  # a hang ends here, not in an orphan
        with Engine(threads=2, library=library) as e2:
            same = cut(e.contact_json(scene, outputs)) == before and cut(e2.contact_json(scene, outputs)) == before
        os._exit(0 if same else 3)
    print(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
"""

OTHER_OPENMP = """
#include <omp.h>
int other_parallel(void) {
    int n = 0;
#pragma omp parallel num_threads(2) reduction(+ : n)
    n += 1;
    return n;
}
"""


@pytest.mark.parametrize("started_by", ["the engine", "other code"])
def test_a_forked_child_evaluates(paths, tmp_path, started_by):
    """A process forked after OpenMP's threads started (multiprocessing's
    default on Linux), by an evaluation on two threads or by other OpenMP
    code in the process: the child evaluates with threads asked for, on one
    (OpenMP's threads do not survive fork; the same bits); before, its first
    evaluation with threads never returned. The elapsed field aside, the
    child's answers equal the parent's."""
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(load(paths, "periodic_packing")))
    other = ""
    if started_by == "other code":
        (tmp_path / "other.c").write_text(OTHER_OPENMP)
        other = str(tmp_path / "libother.so")
        built = subprocess.run(["cc", "-fopenmp", "-shared", "-fPIC", "-o", other, str(tmp_path / "other.c")],
                               capture_output=True, text=True)
        if built.returncode != 0:
            pytest.skip("no C compiler with OpenMP: " + built.stderr[-200:])
    got = subprocess.run([sys.executable, "-c", FORKED, str(LIBRARY), str(scene), other], capture_output=True,
                         text=True, timeout=300, env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    assert got.returncode == 0 and got.stdout.strip() == "0", got.stdout + got.stderr


def test_a_missing_library_says_how_to_get_it(monkeypatch, tmp_path):
    monkeypatch.setenv("NTSCONTACT_LIBRARY", str(tmp_path / "nowhere.so"))
    with pytest.raises(EngineUnavailable) as info:
        Engine()
    assert "NTSCONTACT_LIBRARY" in str(info.value) and info.value.code == "engine_unavailable"
    not_ours = tmp_path / "libnotours.so"
    not_ours.write_bytes(b"not a library")
    with pytest.raises(EngineUnavailable):
        Engine(library=not_ours)
    assert issubclass(EngineUnavailable, ImportError)
    assert os.environ["NTSCONTACT_LIBRARY"].endswith("nowhere.so")


def test_sessions_outlive_their_engine(paths):
    scene = load(paths, "two_disks")
    pos = positions_of(scene)
    e = Engine(library=LIBRARY)
    s = e.session(scene)
    want = e.contact(with_positions(scene, pos)).force_array()
    e.close()
    with pytest.raises(ntscontact.NtsError):
        e.contact(scene)
    assert np.array_equal(s.contact(pos, outputs=["forces"]).force_array(), want)
    s.close()
    s.close()  # twice is fine


def test_bad_thread_counts_are_refused_at_once():
    for bad in (-1, 1025, "2", True, np.bool_(True), 2.0, np.float64(2.0), np.int64(1025)):
        with pytest.raises(ValueError, match="threads"):
            Engine(threads=bad, library=LIBRARY)
    # numpy's integers are integers (and max_bytes takes them too)
    with Engine(threads=np.int64(2), library=LIBRARY, max_bytes=np.int32(1 << 20)) as e:
        assert e.threads == 2 and type(e.threads) is int and e.max_bytes == 1 << 20 and type(e.max_bytes) is int


def test_a_session_that_fails_to_start_leaves_nothing_behind(paths):
    import sys
    seen = []
    old, sys.unraisablehook = sys.unraisablehook, seen.append
    try:
        with Engine(library=LIBRARY) as e:
            for bad in ({"bodies": []}, "not json", {"options": {"penalty": -1}, "bodies": load(paths, "two_disks")["bodies"]}):
                with pytest.raises((InvalidScene, ValueError)):
                    e.session(bad)
        import gc
        gc.collect()
    finally:
        sys.unraisablehook = old
    assert seen == []  # no error from __del__ of a half-made session


def test_info_and_close_from_two_threads(paths):
    """info() against close() on another thread: a closed session raises, none crashes."""
    scene = load(paths, "two_disks")
    e = Engine(library=LIBRARY)
    current = [e.session(scene)]
    stop = threading.Event()
    outcomes = {"info": 0, "closed": 0}

    def reader():
        while not stop.is_set():
            try:
                assert current[0].info()["nodes"] == 96
                outcomes["info"] += 1
            except ntscontact.NtsError as exc:
                assert exc.code == "closed"
                outcomes["closed"] += 1

    t = threading.Thread(target=reader)
    t.start()
    for _ in range(300):
        s = current[0]
        current[0] = e.session(scene)
        s.close()
    stop.set()
    t.join()
    current[0].close()
    with pytest.raises(ntscontact.NtsError):
        current[0].info()
    assert outcomes["info"] > 0


def test_close_waits_for_calls_in_flight(paths):
    scene = load(paths, "periodic_packing")
    e = Engine(library=LIBRARY)
    results = []

    def caller():
        for _ in range(20):
            try:
                results.append(e.contact_json(scene))
            except ntscontact.NtsError as exc:
                results.append(exc.code)

    t = threading.Thread(target=caller)
    t.start()
    e.close()
    t.join()
    assert all(r == "closed" or r.startswith(b'{"version"') for r in results) and len(results) == 20


def test_each_result_knows_its_own_positions_whatever_the_threads(paths):
    scene = load(paths, "two_disks")
    moves = list(walk(scene, 12, 8))
    bad = []
    with Engine(library=LIBRARY) as e, e.session(scene) as s:
        def work(i):
            for k in range(40):
                x = moves[(i + k) % len(moves)]
                r = s.contact(x, outputs=["forces"])
                if not np.array_equal(r._scene[1], x):
                    bad.append(k)

        threads = [threading.Thread(target=work, args=(i,)) for i in range(3)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert bad == []


@pytest.mark.parametrize("text, code, pointer", [
    ('{"a": [1, 2.5e3, "x", true, null]}', None, None),
    ('{"a": 1} x', "invalid_json", ""),
    ('{"a": [1, 02]}', "invalid_json", "/a/1"),
    ('{"a": "\\u0000"}', "invalid_json", "/a"),
    ('[' * 40 + ']' * 40, "too_deep", None),
    ('', "invalid_json", ""),
    ('{"a~b": {"c/d": [0, tru]}}', "invalid_json", "/a~0b/c~1d/1"),
])
def test_json_check_is_the_requests_own_scan(text, code, pointer):
    """ntsj_json_check (codec.h), the check ntscontact-mpi's --part runs on
    each part: NULL for JSON, else the code a request would get, with its
    pointer and a message that says where (line, column), each cut to
    the room given and NUL-terminated."""
    import ctypes
    lib = ctypes.CDLL(str(LIBRARY))
    check = lib.ntsj_json_check
    check.restype = ctypes.c_char_p
    check.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t,
                      ctypes.c_char_p, ctypes.c_size_t]
    data = text.encode()
    where, why = ctypes.create_string_buffer(b"\xff" * 256), ctypes.create_string_buffer(b"\xff" * 256)
    got = check(data, len(data), 0, where, 256, why, 256)
    if code is None:
        assert got is None and where.value == b"" and why.value == b""
        return
    assert got is not None and got.decode() == code
    if pointer is not None:
        assert where.value.decode() == pointer
    assert b"column" in why.value or code == "too_deep", why.value
    small, tiny = ctypes.create_string_buffer(b"\xff" * 8), ctypes.create_string_buffer(b"\xff" * 4)
    assert check(data, len(data), 0, small, 3, tiny, 4).decode() == code
    assert len(small.raw[:3].split(b"\0")[0]) <= 2 and len(tiny.value) <= 3 and small.raw[3:8] == b"\xff" * 5


def test_a_session_of_no_bodies_is_refused(engine):
    """A session holds a whole scene: no bodies is `empty_scene` before
    anything is sent (only a rank's part of a distributed scene,
    ntscontact.mpi, may hold none)."""
    for scene in ({"options": {"penalty": 1.0}, "bodies": []}, ntscontact.Scene(penalty=1.0)):
        with pytest.raises(InvalidScene) as info:
            engine.session(scene)
        assert info.value.code == "empty_scene" and info.value.pointer == "/bodies"


@pytest.mark.parametrize("body, pointer", [({"id": 0, "nodes": "x"}, "/bodies/0/nodes"),
                                           ({"id": 0, "nodes": [[0, 0], [1]]}, "/bodies/0/nodes"),
                                           (5, "/bodies/0")])
def test_a_session_of_bodies_not_so_is_refused_where_they_are(engine, body, pointer):
    """Nodes that are not [x, y] pairs, or a body that is not an object, are
    the service's invalid_type at their place (the client's copy of the
    positions raised numpy's ValueError, or AttributeError)."""
    with pytest.raises(InvalidScene) as info:
        engine.session({"options": {"penalty": 1.0}, "bodies": [body]})
    assert info.value.code == "invalid_type" and info.value.pointer == pointer
