"""ntscontact.mpi (docs/distributed.md): under `mpirun -np N`, N = 1..4, each
rank's DistributedSession of the bodies it owns (scattered: body b on rank
b mod N) steps a random walk together with the others, and every step's
energy, virial, counts and this rank's forces are the bits the in-process
Engine gives on the whole scene; a bad body or bad positions on one rank
raise the same error on every rank (nothing hangs). Skipped without MPI in
the build or mpi4py."""
import os
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

from conftest import BUILD

MPI_LIB = BUILD / "lib" / "libntscontact_mpi_engine.so"
ENGINE_LIB = BUILD / "lib" / "libntscontact_engine.so"
MPIRUN = shutil.which("mpirun")

try:
    import mpi4py  # noqa: F401
    HAVE_MPI4PY = True
except ImportError:
    HAVE_MPI4PY = False

pytestmark = pytest.mark.skipif(not MPI_LIB.exists() or MPIRUN is None or not HAVE_MPI4PY,
                                reason="no libntscontact_mpi_engine.so (-DNTS_MPI=ON), mpirun or mpi4py")

SCRIPT = textwrap.dedent('''
    import math, sys
    import numpy as np
    from mpi4py import MPI
    import ntscontact
    from ntscontact.errors import NtsError
    import ntscontact.mpi

    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    rng = np.random.default_rng(5)

    def disk(cx, cy, r, n, ph):
        t = ph + 2 * math.pi * np.arange(n) / n
        return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1)

    side, bodies = 9, []
    for b in range(side * side):
        bodies.append(disk(b % side + 0.5 + 0.03 * rng.standard_normal(), b // side + 0.5,
                           0.54 * rng.uniform(0.92, 1.04), 16 + b % 5, rng.uniform()))
    bodies.append(np.array([[-1.0, -0.45], [side + 1.0, -0.45], [side + 1.0, 0.03], [-1.0, 0.03]]))
    options = {"penalty": 10.0, "alpha": 0.2}

    def scene(ids):
        return {"options": options, "bodies": [{"id": i, "nodes": bodies[i].tolist()} for i in ids]}

    whole = list(range(len(bodies)))
    mine = [b for b in whole if b % size == rank]
    ref = ntscontact.Engine().session(scene(whole))
    eng = ntscontact.mpi.DistributedEngine(comm)
    part = eng.session(scene(mine))
    pos = np.concatenate(bodies)
    offsets = np.concatenate([[0], np.cumsum([len(x) for x in bodies])])
    for step in range(5):
        pos = pos + 0.003 * rng.standard_normal(pos.shape)
        my_pos = np.concatenate([pos[offsets[b]:offsets[b + 1]] for b in mine])
        a = ref.step(pos)
        d = part.step(my_pos, outputs=["forces", "energy", "virial"] if step % 2 else None)
        assert np.float64(d.energy).tobytes() == np.float64(a.energy).tobytes(), (step, d.energy, a.energy)
        assert np.asarray(d.virial).tobytes() == np.asarray(a.virial).tobytes(), step
        assert (d.summary.contacts, d.summary.gaps, d.summary.deep_contacts) == \\
            (a.summary.contacts, a.summary.gaps, a.summary.deep_contacts), step
        want = np.concatenate([a.force_array()[offsets[b]:offsets[b + 1]] for b in mine])
        assert d.force_array().tobytes() == want.tobytes(), step
    assert a.summary.contacts > 50
    # a rank whose bodies did not move may pass None: the same answer
    d = part.step(None if rank == 0 else my_pos)
    assert np.float64(d.energy).tobytes() == np.float64(a.energy).tobytes()
    assert d.summary.bodies == len(bodies)

    # a body mirrored (its loop turned over): one process's session makes its
    # scene anew and answers, and so must the ranks' (they refused it); then
    # a step more from the scene made anew
    b0 = 40
    for step in range(2):
        if step == 0:
            sl = slice(offsets[b0], offsets[b0 + 1])
            cx = pos[sl, 0].mean()
            pos[sl, 0] = 2.0 * cx - pos[sl, 0]
        else:
            pos = pos + 0.002 * rng.standard_normal(pos.shape)
        my_pos = np.concatenate([pos[offsets[b]:offsets[b + 1]] for b in mine])
        a = ref.step(pos)
        d = part.step(my_pos)
        assert np.float64(d.energy).tobytes() == np.float64(a.energy).tobytes(), ("mirrored", step, d.energy, a.energy)
        assert d.summary.contacts == a.summary.contacts and d.summary.loops_reversed == a.summary.loops_reversed, step
        want = np.concatenate([a.force_array()[offsets[b]:offsets[b + 1]] for b in mine])
        assert d.force_array().tobytes() == want.tobytes(), ("mirrored", step)
    assert a.summary.contacts > 50

    # the last rank owns no body (more ranks than a host's shares): it steps
    # with an empty array, or None, and gets the whole's summary; the others
    # their forces, the same bits
    if size > 1:
        held = [b for b in whole if b % (size - 1) == rank] if rank < size - 1 else []
        empty = eng.session(scene(held))
        assert empty.nodes == sum(len(bodies[b]) for b in held)
        for step in range(3):
            pos = pos + 0.003 * rng.standard_normal(pos.shape)
            held_pos = np.concatenate([np.zeros((0, 2))] + [pos[offsets[b]:offsets[b + 1]] for b in held])
            a = ref.step(pos)
            d = empty.step(None if (rank == size - 1 and step == 1) else held_pos)
            assert np.float64(d.energy).tobytes() == np.float64(a.energy).tobytes(), (step, d.energy, a.energy)
            assert np.asarray(d.virial).tobytes() == np.asarray(a.virial).tobytes(), step
            assert d.summary.contacts == a.summary.contacts and d.summary.bodies == len(bodies), step
            want = np.concatenate([np.zeros((0, 2))] + [a.force_array()[offsets[b]:offsets[b + 1]] for b in held])
            assert d.force_array().shape == want.shape and d.force_array().tobytes() == want.tobytes(), step
        empty.close()
        pos = pos - 0.0  # (the walk goes on from here)
        my_pos = np.concatenate([pos[offsets[b]:offsets[b + 1]] for b in mine])
        a = ref.step(pos)
        part.step(my_pos)

    # bad positions: every rank raises the error one process raises for the
    # whole's positions (the whole's first bad row, its body and node, x or
    # y), not a rank's own row, nor the lowest failing rank's: a NaN at the
    # last rank's first body's first x, and with more ranks, one at rank
    # 0's last body's third y (a later row of the whole)
    whole_bad = pos.copy()
    whole_bad[offsets[size - 1], 0] = float("nan")
    if size > 1:
        whole_bad[offsets[[b for b in whole if b % size == 0][-1]] + 2, 1] = float("inf")
    try:
        ref.step(whole_bad)
        raise SystemExit("NaN positions accepted by one process")
    except NtsError as exc:
        want = (exc.code, exc.pointer, exc.message)
    assert want[0] == "non_finite" and want[1] == f"/positions/{offsets[size - 1]}", want
    try:
        part.step(np.concatenate([whole_bad[offsets[b]:offsets[b + 1]] for b in mine]))
        raise SystemExit("NaN positions accepted")
    except NtsError as exc:
        assert (exc.code, exc.pointer, exc.message) == want, ((exc.code, exc.pointer, exc.message), want)

    # a degenerate body on the last rank only
    broken = scene(mine)
    if rank == size - 1:
        nodes = broken["bodies"][0]["nodes"]
        nodes[1] = list(nodes[0])
    try:
        eng.session(broken)
        raise SystemExit("a degenerate body accepted")
    except NtsError as exc:
        seen = comm.allgather((exc.code, exc.pointer))
        assert all(s == seen[0] for s in seen), seen
        want_body = mine[0] if rank == size - 1 else None
        want_body = comm.bcast(want_body, root=size - 1)
        assert exc.pointer.startswith(f"/bodies/{want_body}"), (exc.pointer, want_body)
    # faults a part's document holds (an unknown field), on two bodies of the
    # last rank held in descending order: the body one process names
    held = sorted(mine, reverse=True)
    bad = sorted(held)[:2] if rank == size - 1 else []
    every_bad = comm.bcast(bad, root=size - 1)
    doc = scene(held)
    for b in doc["bodies"]:
        if b["id"] in bad:
            b["colour"] = "red"
    whole_doc = scene(whole)
    for b in whole_doc["bodies"]:
        if b["id"] in every_bad:
            b["colour"] = "red"
    try:
        ntscontact.Engine().session(whole_doc)
        raise SystemExit("one process took an unknown field")
    except NtsError as exc:
        want = (exc.code, exc.pointer)
    try:
        eng.session(doc, ids=held)
        raise SystemExit("an unknown field accepted")
    except NtsError as exc:
        seen = comm.allgather((exc.code, exc.pointer))
        assert all(x == want for x in seen), (seen, want)

    # every rank's part empty: no scene, empty_scene at /bodies on every rank
    try:
        eng.session(scene([]))
        raise SystemExit("a scene of no bodies accepted")
    except NtsError as exc:
        seen = comm.allgather((exc.code, exc.pointer))
        assert all(x == ("empty_scene", "/bodies") for x in seen), seen

    # two degenerate bodies on the last rank, held in descending order: the
    # body one process names (the lower), by its global index in the
    # pointer and the message alike, on every rank
    held = sorted(mine, reverse=True)
    broken = scene(held)
    bad = sorted(held)[:2] if rank == size - 1 else []
    for b in broken["bodies"]:
        if b["id"] in bad:
            b["nodes"][1] = list(b["nodes"][0])
    whole_doc = scene(whole)
    for b in whole_doc["bodies"]:
        if b["id"] in comm.bcast(bad, root=size - 1):
            b["nodes"][1] = list(b["nodes"][0])
    try:
        ntscontact.Engine().session(whole_doc)
        raise SystemExit("one process took a degenerate body")
    except NtsError as exc:
        want = (exc.code, exc.pointer)
        want_body = int(exc.pointer.split("/")[2])
    try:
        eng.session(broken, ids=held)
        raise SystemExit("two degenerate bodies accepted")
    except NtsError as exc:
        seen = comm.allgather((exc.code, exc.pointer, str(exc)))
        assert all(x == seen[0] for x in seen), seen
        assert (exc.code, exc.pointer) == want, ((exc.code, exc.pointer), want)
        assert f"body {want_body} " in str(exc), str(exc)
    part.close()
    sys.stdout.write(f"OK rank {rank}/{size}\\n")
    sys.stdout.flush()
''')


@pytest.mark.parametrize("ranks", [1, 2, 3, 4])
def test_distributed_session_bitwise(tmp_path, ranks):
    script = tmp_path / "steps.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", NTSCONTACT_MPI_LIBRARY=str(MPI_LIB),
               NTSCONTACT_LIBRARY=str(ENGINE_LIB))
    r = subprocess.run([MPIRUN, "-np", str(ranks), "--oversubscribe", sys.executable, str(script)],
                       capture_output=True, timeout=600, env=env)
    out = r.stdout.decode()
    assert r.returncode == 0, out + r.stderr.decode()[-3000:]
    # (mpirun may interleave the ranks' lines)
    assert sorted(re.findall(r"OK rank \d+/\d+", out)) == sorted(f"OK rank {k}/{ranks}" for k in range(ranks)), out
