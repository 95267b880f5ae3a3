"""ntscontact-mpi (docs/distributed.md): under `mpirun -np N`, N = 1..4, its
output is the bytes ntscontact writes for the same scene and options
(elapsed_ms aside): open and periodic packings, long walls, bodies spanning
several slabs and larger than a rank's domain, more ranks than cells along an
axis, deep contacts, friction, self-contact, contact surfaces, meshes, every
output, --frames; and a bad scene gives the same error and exit code. Skipped when the
build has no MPI (-DNTS_MPI=ON)."""
import json
import math
import os
import random
import re
import struct
import shutil
import subprocess

import pytest

from conftest import BUILD, full_disk

MPI_CLI = BUILD / "bin" / "ntscontact-mpi"
SERIAL = BUILD / "bin" / "ntscontact"
MPIRUN = shutil.which("mpirun")

pytestmark = pytest.mark.skipif(not MPI_CLI.exists() or MPIRUN is None,
                                reason="no ntscontact-mpi in this build (-DNTS_MPI=ON) or no mpirun")

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_btl_vader_single_copy_mechanism="none")
ELAPSED = re.compile(rb'"elapsed_ms":\s*[-0-9.eE+]+')
ALL = "forces,energy,virial,contacts,gaps,stiffness,pressure"


def polygon(cx, cy, r, n, phase=0.0):
    return [[cx + r * math.cos(phase + 2 * math.pi * k / n), cy + r * math.sin(phase + 2 * math.pi * k / n)]
            for k in range(n)]


def packing(count, seed, periodic=False, overlap=1.08, n=24):
    """Disks on a jittered grid, pressed into each other (radius `overlap` x half the spacing)."""
    rng = random.Random(seed)
    side = int(math.ceil(math.sqrt(count)))
    bodies = []
    for i in range(count):
        x, y = (i % side) + 0.5, (i // side) + 0.5
        r = 0.5 * overlap * rng.uniform(0.9, 1.05)
        bodies.append({"nodes": polygon(x + rng.uniform(-0.04, 0.04), y + rng.uniform(-0.04, 0.04), r, n,
                                        rng.uniform(0, 1))})
    scene = {"bodies": bodies}
    if periodic:
        scene["options"] = {"penalty": 1.0, "periodic": {"lx": float(side), "ly": float(side)}}
    return scene


def rectangle(x0, y0, x1, y1, per_side):
    pts = []
    for k in range(per_side):
        pts.append([x0 + (x1 - x0) * k / per_side, y0])
    for k in range(per_side):
        pts.append([x1, y0 + (y1 - y0) * k / per_side])
    for k in range(per_side):
        pts.append([x1 - (x1 - x0) * k / per_side, y1])
    for k in range(per_side):
        pts.append([x0, y1 - (y1 - y0) * k / per_side])
    return pts


def run(cmd, scene_path, flags, np_=None):
    argv = [str(cmd), *flags, str(scene_path)]
    if np_ is not None:
        argv = [MPIRUN, "-np", str(np_), "--oversubscribe", *argv]
    return subprocess.run(argv, capture_output=True, timeout=300, env=ENV)


def completed(scene):
    """A scene with what a request needs and the generators leave out: a penalty and the bodies' ids."""
    scene.setdefault("options", {}).setdefault("penalty", 1.0)
    for i, b in enumerate(scene["bodies"]):
        b.setdefault("id", i)
    return scene


def same_bytes(tmp_path, scene, flags=(), ranks=(1, 2, 3, 4)):
    path = tmp_path / "scene.json"
    if isinstance(scene, dict):
        path.write_text(json.dumps(completed(scene)))
    else:
        path = scene
    ref = run(SERIAL, path, flags)
    assert ref.returncode == 0, ref.stderr.decode()
    want = ELAPSED.sub(b"", ref.stdout)
    for n in ranks:
        got = run(MPI_CLI, path, flags, n)
        assert got.returncode == 0, f"np={n}: {got.stderr.decode()}"
        assert ELAPSED.sub(b"", got.stdout) == want, f"np={n}: differs from ntscontact ({' '.join(flags)})"
    return json.loads(ref.stdout)


@pytest.mark.parametrize("example", ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"])
@pytest.mark.parametrize("outputs", [None, ALL])
def test_examples_bitwise(tmp_path, paths, example, outputs):
    flags = ("--outputs", outputs) if outputs else ()
    same_bytes(tmp_path, paths.examples / f"{example}.json", flags)


def test_open_packing_every_output(tmp_path):
    r = same_bytes(tmp_path, packing(150, 1), ("--outputs", ALL))
    assert r["summary"]["contacts"] > 300


def test_periodic_packing(tmp_path):
    r = same_bytes(tmp_path, packing(144, 2, periodic=True), ("--outputs", "forces,contacts,gaps"))
    assert r["summary"]["contacts"] > 300


def test_options(tmp_path):
    scene = packing(64, 3)
    for flags in (("--alpha", "0"), ("--alpha", "0.5", "--solver", "newton"), ("--search-radius", "0.05"),
                  ("--penalty", "1e3", "--outputs", "forces,stiffness")):
        same_bytes(tmp_path, scene, flags, ranks=(2, 4))


def test_explicit_radius_warning(tmp_path):
    """Deeper than an explicit radius: left out, and counted the same."""
    scene = packing(36, 4, overlap=1.4)
    r = same_bytes(tmp_path, scene, ("--search-radius", "0.02"), ranks=(1, 3))
    assert r.get("warnings"), "the scene should leave contacts out"


def test_deep_contacts_and_a_body_larger_than_a_slab(tmp_path):
    """A big disk over many small ones, some deep inside it: its box spans every slab."""
    scene = packing(100, 5)
    scene["bodies"].append({"nodes": polygon(5.0, 5.0, 2.2, 400)})
    r = same_bytes(tmp_path, scene, ("--outputs", "forces,contacts,gaps"))
    assert r["summary"]["deep_contacts"] > 0


def test_long_walls(tmp_path):
    """A floor and a ceiling as long as the scene, disks between them."""
    scene = packing(60, 6)
    scene["bodies"].append({"nodes": rectangle(-1.0, -0.45, 11.0, 0.05, 200), "alpha": 0.0})
    scene["bodies"].append({"nodes": rectangle(-1.0, 6.0, 11.0, 6.5, 200), "alpha": 0.0})
    same_bytes(tmp_path, scene, ("--outputs", "forces,contacts,stiffness"))


def test_more_ranks_than_cells(tmp_path):
    """Two disks: 4 ranks, most with no slave at all."""
    scene = {"bodies": [{"nodes": polygon(0, 0, 1, 40)}, {"nodes": polygon(1.9, 0.1, 1, 40)}]}
    same_bytes(tmp_path, scene, ("--outputs", ALL))


def test_friction_self_contact_surfaces(tmp_path):
    scene = packing(49, 7)
    scene["options"] = {"penalty": 1.0, "friction": {"coefficient": 0.3}}
    same_bytes(tmp_path, scene, ("--outputs", "forces,contacts,stiffness"), ranks=(2, 3))
    ring = packing(25, 8)
    for b in ring["bodies"][::3]:
        b["self_contact"] = True
    same_bytes(tmp_path, ring, (), ranks=(2, 4))
    surf = {"bodies": [{"nodes": rectangle(0, 0, 2, 1, 8), "surface": [[k, k + 1] for k in range(7)] + [[7, 8]]},
                       {"nodes": rectangle(0, 0.99, 2, 2, 8)}]}
    same_bytes(tmp_path, surf, ("--outputs", "forces,contacts"), ranks=(1, 2))


def test_friction_switched_on_the_whole_scene(tmp_path):
    """Friction runs when some pair of the whole scene that can meet rubs
    (docs/model.md §14), decided on the whole, not on a rank's part: a pair
    at 0 (the options' 0.4, one body's own 0) beside a pair that rubs, far
    apart, so that a rank may hold the first pair alone; and a scene whose
    only coefficients are bodies' own. Every rank count gives the serial
    bytes (a part of the first pair alone took friction off: a contact's
    tangential force -0.0 for 0.0, half the anchors)."""
    bodies = [{"nodes": polygon(0.0, 0.0, 1.0, 24)}, {"nodes": polygon(1.95, 0.0, 1.0, 24), "friction": 0.0},
              {"nodes": polygon(40.0, 0.0, 1.0, 24)}, {"nodes": polygon(41.95, 0.05, 1.0, 24)}]
    scene = {"options": {"penalty": 10.0, "friction": {"coefficient": 0.4}}, "bodies": bodies}
    same_bytes(tmp_path, scene, ("--outputs", "forces,contacts,stiffness"), ranks=(2, 3, 4))
    own = {"options": {"penalty": 10.0}, "bodies": [dict(b) for b in bodies]}
    own["bodies"][1]["friction"] = 0.0
    own["bodies"][2]["friction"] = 0.5
    own["bodies"][3]["friction"] = 0.3
    same_bytes(tmp_path, own, ("--outputs", "forces,contacts"), ranks=(2, 4))


@pytest.mark.parametrize("bad", [
    {"bodies": [{"nodes": [[0, 0], [1, 0], [1, 0], [0, 1]]}, {"nodes": polygon(3, 0, 1, 8)}]},
    {"bodies": [{"nodes": polygon(0, 0, 1, 8)}, {"nodes": [[0, 0], [1, 0]]}]},
    {"bodies": [{"nodes": polygon(0, 0, 1, 8)}, {"nodes": polygon(1.5, 0, 1, 8)}],
     "options": {"penalty": 1.0, "periodic": {"lx": 3.0, "ly": 3.0}}},
])
def test_bad_scene_same_error(tmp_path, bad):
    path = tmp_path / "bad.json"
    bad = dict(bad)
    bad.setdefault("options", {"penalty": 1.0})
    bad["bodies"] = [dict(b, id=i) for i, b in enumerate(bad["bodies"])]
    path.write_text(json.dumps(bad))
    ref = run(SERIAL, path, ())
    assert ref.returncode != 0
    for n in (1, 3):
        got = run(MPI_CLI, path, (), n)
        assert got.returncode == ref.returncode
        # (mpirun adds its own notice of the non-zero exit after it); the
        # same message, in the name of the program run
        first = ref.stderr.splitlines()[0]
        assert first.startswith(b"ntscontact: ")
        assert got.stderr.splitlines()[0] == b"ntscontact-mpi: " + first[len(b"ntscontact: "):]


@pytest.mark.parametrize("budget, words", [(5, "within"), (10, "deeper"), (40, "deeper"), (57, "deeper"),
                                            (58, None)])
def test_candidate_budget_as_one_process(tmp_path, budget, words):
    """--max-candidates is the whole's, counted as one process counts it: the
    closest points within the radius, then those deeper, found or (an
    explicit radius) counted and left out. The same verdict and words on
    any number of ranks: "... within the search radius" when those within r
    alone exceed it, "... and deeper" when only the deeper ones take it
    over. Two pairs of disks, each pressed 0.4 into each other, far apart,
    an explicit radius of 0.05: 8 closest points within it, 50 deeper. The
    ranks took 40 (only the found deep ones were counted, not those left
    out), and a part over the budget only at its deeper ones said so where
    the whole is over it within r (5)."""
    pair = [polygon(0, 0, 1, 64), polygon(1.6, 0, 1, 64, 0.01)]
    scene = {"options": {"penalty": 1.0, "search_radius": 0.05},
             "bodies": [{"id": i, "nodes": [[x + dx, y] for x, y in nodes]}
                        for i, (dx, nodes) in enumerate([(0, pair[0]), (0, pair[1]), (10, pair[0]), (10, pair[1])])]}
    path = tmp_path / "deep.json"
    path.write_text(json.dumps(scene))
    ok = run(SERIAL, path, ("--outputs", "gaps"))
    assert ok.returncode == 0
    summary = json.loads(ok.stdout)
    assert summary["summary"]["gaps"] == 8 and summary["warnings"][0]["count"] == 50
    flags = ("--max-candidates", str(budget))
    ref = run(SERIAL, path, flags)
    line = [s for s in ref.stderr.splitlines() if b"limit_exceeded" in s]
    if words is None:
        assert ref.returncode == 0 and line == [], ref.stderr.decode()
    else:
        assert ref.returncode != 0 and len(line) == 1 and (b"and deeper" in line[0]) == (words == "deeper"), \
            ref.stderr.decode()
    for n in (1, 2, 3, 4):
        got = run(MPI_CLI, path, flags, n)
        assert got.returncode == ref.returncode, f"np={n}: {got.stderr.decode()}"
        # the same line, in the name of the program run
        assert [s for s in got.stderr.splitlines() if b"limit_exceeded" in s] == \
            [b"ntscontact-mpi: " + s[len(b"ntscontact: "):] for s in line], f"np={n}: {got.stderr.decode()}"


def test_frames(tmp_path, paths):
    """--frames (a session over frames of positions): the same lines, frame by frame, and the same VTK series."""
    scene = json.loads((paths.examples / "jittered_packing.json").read_text())
    nodes = [p for b in scene["bodies"] for p in b["nodes"]]
    rng = random.Random(9)
    frames = b"".join(struct.pack(f"<{2 * len(nodes)}d", *[c + 0.002 * k * rng.gauss(0, 1) for p in nodes for c in p])
                      for k in range(4))
    (tmp_path / "frames.bin").write_bytes(frames)
    for flags in (("--outputs", "forces,contacts"), ("--outputs", "forces,stiffness,pressure")):
        args = ("--frames", str(tmp_path / "frames.bin"), *flags)
        ref = run(SERIAL, paths.examples / "jittered_packing.json", args)
        assert ref.returncode == 0, ref.stderr.decode()
        assert len(ref.stdout.splitlines()) == 4
        for n in (2, 3):
            got = run(MPI_CLI, paths.examples / "jittered_packing.json", args, n)
            assert got.returncode == 0, got.stderr.decode()
            assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref.stdout), (n, flags)


def test_frames_go_on_with_the_scene(tmp_path, paths):
    """--frames: from the second frame on, the ranks go on with the
    distributed scene of the first (each rank given its bodies' positions;
    the parts and their candidate lists kept while they hold) instead of
    dealing and making it anew: the same lines as ntscontact, frame by frame,
    through small steps, the whole packing moved 5 (every part made again),
    the packing grown 5% (every segment longer), and a body mirrored (its
    loop turned over: one process's session makes its scene anew, and so
    must the ranks, which refused the positions as another scene)."""
    scene = json.loads((paths.examples / "jittered_packing.json").read_text())
    nodes = [p for b in scene["bodies"] for p in b["nodes"]]
    first = len(scene["bodies"][0]["nodes"])
    cx = sum(x for x, _ in nodes[:first]) / first
    rng = random.Random(3)
    frames = []
    for k in range(8):
        row = []
        for i, (x, y) in enumerate(nodes):
            x, y = x + 0.002 * rng.gauss(0, 1), y + 0.002 * rng.gauss(0, 1)
            if k == 3:
                x += 5.0
            if k == 5:
                x, y = 1.05 * x, 1.05 * y
            if k >= 6 and i < first:
                x = 2.0 * cx - x  # body 0 mirrored: its loop turns over
            row += [x, y]
        frames.append(struct.pack(f"<{len(row)}d", *row))
    (tmp_path / "frames.bin").write_bytes(b"".join(frames))
    args = ("--frames", str(tmp_path / "frames.bin"), "--outputs", "forces,contacts,gaps")
    ref = run(SERIAL, paths.examples / "jittered_packing.json", args)
    assert ref.returncode == 0 and len(ref.stdout.splitlines()) == 8, ref.stderr.decode()
    for n in (2, 3, 4):
        got = run(MPI_CLI, paths.examples / "jittered_packing.json", args, n)
        assert got.returncode == 0, got.stderr.decode()
        assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref.stdout), n


def test_vtk_validate_pretty(tmp_path, paths):
    """--vtk writes the same file, --validate and --pretty the same bytes."""
    scene = paths.examples / "jittered_packing.json"
    ref = run(SERIAL, scene, ("--vtk", str(tmp_path / "one.vtu")))
    got = run(MPI_CLI, scene, ("--vtk", str(tmp_path / "many.vtu")), 3)
    assert ref.returncode == 0 and got.returncode == 0, got.stderr.decode()
    assert (tmp_path / "one.vtu").read_bytes() == (tmp_path / "many.vtu").read_bytes()
    for flags in (("--validate",), ("--pretty", "--outputs", "forces,contacts")):
        ref = run(SERIAL, paths.examples / "periodic_packing.json", flags)
        got = run(MPI_CLI, paths.examples / "periodic_packing.json", flags, 2)
        assert got.returncode == 0, got.stderr.decode()
        assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref.stdout), flags


def test_friction_history(tmp_path):
    """Friction's history (docs/model.md §14): --history-in / --history-out
    and --frames (every frame commits) give ntscontact's bytes, anchors too."""
    scene = packing(49, 11)
    scene["options"] = {"penalty": 10.0, "friction": {"coefficient": 0.4}, "outputs": ["forces", "contacts"]}
    for i, b in enumerate(scene["bodies"]):
        b["id"] = i
    first = tmp_path / "first.json"
    first.write_text(json.dumps(scene))
    moved = json.loads(json.dumps(scene))
    for k, b in enumerate(moved["bodies"]):  # every other row slides to the right
        if (k // 7) % 2:
            b["nodes"] = [[x + 0.01, y] for x, y in b["nodes"]]
    second = tmp_path / "second.json"
    second.write_text(json.dumps(moved))
    ref = run(SERIAL, first, ("--history-out", str(tmp_path / "h1.json")))
    assert ref.returncode == 0, ref.stderr.decode()
    ref2 = run(SERIAL, second, ("--history-in", str(tmp_path / "h1.json"), "--history-out", str(tmp_path / "h2.json")))
    assert ref2.returncode == 0 and b'"slipping"' in ref2.stdout
    for n in (2, 3):
        got = run(MPI_CLI, second, ("--history-in", str(tmp_path / "h1.json"), "--history-out",
                                    str(tmp_path / f"m{n}.json")), n)
        assert got.returncode == 0, got.stderr.decode()
        assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref2.stdout), n
        assert (tmp_path / f"m{n}.json").read_bytes() == (tmp_path / "h2.json").read_bytes(), n
    nodes = [p for b in scene["bodies"] for p in b["nodes"]]
    frames = b"".join(struct.pack(f"<{2 * len(nodes)}d", *[c + (0.004 * k if j % 2 == 0 else 0.0)
                                                           for p in nodes for j, c in enumerate(p)])
                      for k in range(4))
    (tmp_path / "frames.bin").write_bytes(frames)
    args = ("--frames", str(tmp_path / "frames.bin"), "--history-out", str(tmp_path / "hf.json"))
    ref = run(SERIAL, first, args)
    assert ref.returncode == 0, ref.stderr.decode()
    got = run(MPI_CLI, first, ("--frames", str(tmp_path / "frames.bin"), "--history-out", str(tmp_path / "mf.json")), 3)
    assert got.returncode == 0, got.stderr.decode()
    assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref.stdout)
    assert (tmp_path / "mf.json").read_bytes() == (tmp_path / "hf.json").read_bytes()


def test_part_each_rank_reads_its_own(tmp_path):
    """--part PATTERN: rank r reads PATTERN with %d = r; the answer is
    ntscontact's on the parts' bodies in rank order. A missing part, or parts
    whose options differ, fail on every rank with a message."""
    scene = packing(60, 12, periodic=True)
    scene["options"]["penalty"] = 3.0
    for i, b in enumerate(scene["bodies"]):
        b["id"] = f"disk-{i}"
    whole = tmp_path / "whole.json"
    for n in (1, 2, 3):
        share = [scene["bodies"][k::n] for k in range(n)]  # each rank a scattered share
        ordered = dict(scene, bodies=[b for part in share for b in part])
        whole.write_text(json.dumps(ordered))
        for r in range(n):
            (tmp_path / f"part_{r}.json").write_text(json.dumps(dict(scene, bodies=share[r])))
        ref = run(SERIAL, whole, ("--outputs", "forces,contacts"))
        assert ref.returncode == 0, ref.stderr.decode()
        argv = [MPIRUN, "-np", str(n), "--oversubscribe", str(MPI_CLI), "--outputs", "forces,contacts",
                "--part", str(tmp_path / "part_%d.json")]
        got = subprocess.run(argv, capture_output=True, timeout=300, env=ENV)
        assert got.returncode == 0, got.stderr.decode()
        assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", ref.stdout), n
    (tmp_path / "part_1.json").unlink()
    argv = [MPIRUN, "-np", "3", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json")]
    got = subprocess.run(argv, capture_output=True, timeout=300, env=ENV)
    assert got.returncode == 2 and b"rank 1 cannot read" in got.stderr, got.stderr.decode()
    (tmp_path / "part_1.json").mkdir()  # a directory: said so (it was "cannot read ... whole")
    got = subprocess.run(argv, capture_output=True, timeout=300, env=ENV)
    assert got.returncode == 2 and b"rank 1 cannot read" in got.stderr and b"Is a directory" in got.stderr, \
        got.stderr.decode()
    (tmp_path / "part_1.json").rmdir()
    # options that differ by 4, or by one unit in the last place (cJSON_Compare took that for equal)
    for penalty in (4.0, math.nextafter(3.0, 4.0)):
        (tmp_path / "part_1.json").write_text(json.dumps(dict(scene, bodies=scene["bodies"][:2],
                                                             options=dict(scene["options"], penalty=penalty))))
        got = subprocess.run(argv, capture_output=True, timeout=300, env=ENV)
        assert got.returncode == 3 and b"options differ" in got.stderr, (penalty, got.stderr.decode())
    # --part with no value: its own usage error (the CLI called it an unknown option)
    got = subprocess.run([MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part"], capture_output=True,
                         timeout=300, env=ENV)
    assert got.returncode == 2 and b"--part needs a value" in got.stderr and b"unknown option" not in got.stderr


@pytest.mark.parametrize("fault, code, where", [
    ("trailing", b"invalid_json", b'at "" of part 1: unexpected data after the JSON value'),
    ("leading_zero", b"invalid_json", b'at "/options/penalty" of part 1: leading zero'),
    ("overflow", b"non_finite", b'at "/bodies/0/nodes/2/1" of part 1'),
    ("bom", b"invalid_json", b'at "" of part 1'),
    ("empty", b"empty_body", b'at "" of part 1'),
    ("duplicate", b"duplicate_key", b'at "/bodies" of part 1: key "bodies" appears more than once'),
    ("unknown", b"unknown_field", b'at "/bodiez" of part 1'),
    ("history", b"invalid_value", b'at "/history" of part 1: only part 0'),
    ("version", b"invalid_value", b'at "/version" of part 1'),
    ("schema", b"invalid_value", b'at "/$schema" of part 1'),
    ("blank", b"empty_body", b'at "" of part 1'),
    ("escaped", b"unknown_field", b'at "/a~1b~0c" of part 1'),
    ("array", b"invalid_type", b'at "" of part 1: expected a scene (an object), got an array'),
    ("no_bodies", b"missing_field", b'at "/bodies" of part 1: a part needs "bodies"'),
    ("misspelt_bodies", b"unknown_field", b'at "/bodiez" of part 1: unknown field'),
    ("bodies_number", b"invalid_type", b'at "/bodies" of part 1: expected an array of bodies, got a number'),
])
def test_part_read_as_strictly_as_a_request(tmp_path, fault, code, where):
    """--part: each part is checked as a request is (strict RFC 8259; a
    number beyond the doubles is refused), and the fault is named in its
    part (JSON pointer, part index), on rank 0, with the input's exit code 3.
    cJSON alone took trailing data and a leading zero, and 1e999 came out
    as invalid JSON at a place of the assembled request; a key twice, a
    field no scene has, a history or another version in a part after the
    first were dropped from the assembled request without a word."""
    scene = packing(8, 21)
    scene["options"] = {"penalty": 2.0}
    share = [scene["bodies"][:4], scene["bodies"][4:]]
    (tmp_path / "part_0.json").write_text(json.dumps(dict(scene, bodies=share[0])))
    text = json.dumps(dict(scene, bodies=share[1]))
    if fault == "trailing":
        text += " {}"
    elif fault == "leading_zero":
        text = text.replace('"penalty": 2.0', '"penalty": 02.0')
    elif fault == "overflow":
        nodes = share[1][0]["nodes"]
        text = text.replace(json.dumps(nodes[2]), "[%r, 1e999]" % nodes[2][0], 1)
    elif fault == "bom":
        text = "\ufeff" + text
    elif fault == "empty":
        text = ""
    elif fault == "duplicate":  # the first "bodies" empty: the second's bodies were dropped
        text = text.replace('"bodies": [', '"bodies": [], "bodies": [', 1)
    elif fault == "unknown":
        text = text.replace('"bodies": [', '"bodiez": 1, "bodies": [', 1)
    elif fault == "history":
        text = text.replace('"bodies": [', '"history": [], "bodies": [', 1)
    elif fault == "version":
        text = text.replace('"bodies": [', '"version": 1, "bodies": [', 1)  # part 0 has none
    elif fault == "schema":
        text = text.replace('"bodies": [', '"$schema": "x", "bodies": [', 1)
    elif fault == "blank":
        text = " \n\t "
    elif fault == "array":  # (each of these three was invalid_json, which the text is not)
        text = "[" + text + "]"
    elif fault == "misspelt_bodies":
        text = text.replace('"bodies": [', '"bodiez": [', 1)
    elif fault == "no_bodies":
        text = json.dumps({"options": scene["options"]})
    elif fault == "bodies_number":
        text = json.dumps(dict(scene, bodies=3))
    else:
        text = text.replace('"bodies": [', '"a/b~c": 1, "bodies": [', 1)
    (tmp_path / "part_1.json").write_text(text, encoding="utf-8")
    argv = [MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json")]
    got = subprocess.run(argv, capture_output=True, timeout=300, env=ENV)
    assert got.returncode == 3, got.stderr.decode()
    assert got.stdout == b""
    line = [s for s in got.stderr.splitlines() if s.startswith(b"ntscontact-mpi:")]
    assert len(line) == 1 and code in line[0] and where in line[0], got.stderr.decode()


def test_part_read_with_the_command_lines_max_depth(tmp_path):
    """--part reads its parts with the command line's --max-depth, as the
    CLI reads a request (they were read with the default, 32, whatever it
    said), and a bad flag is refused with the CLI's own message before any
    part is read."""
    scene = packing(8, 22)
    share = [scene["bodies"][:4], scene["bodies"][4:]]
    (tmp_path / "part_0.json").write_text(json.dumps(dict(scene, bodies=share[0])))
    deep = "[" * 40 + "]" * 40  # 41 levels with the document's own
    text = json.dumps(dict(scene, bodies=share[1])).replace('"bodies": [', '"deep": %s, "bodies": [' % deep, 1)
    (tmp_path / "part_1.json").write_text(text)
    base = [MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json")]

    def fault(*flags):
        got = subprocess.run(base + list(flags), capture_output=True, timeout=300, env=ENV)
        line = [s for s in got.stderr.splitlines() if s.startswith((b"ntscontact-mpi:", b"ntscontact:"))]
        assert got.stdout == b"" and len(line) >= 1, got.stderr.decode()
        return got.returncode, line[0]

    rc, line = fault()  # the default depth: the deep member is too deep
    assert rc == 3 and b'too_deep at "/deep/0/' in line and b"of part 1" in line, line
    rc, line = fault("--max-depth", "64")  # deep enough: the member is read, and refused as unknown
    assert rc == 3 and b'unknown_field at "/deep" of part 1' in line, line
    rc, line = fault("--max-depth=3")  # the nodes' pairs of part 0 are 4 deep
    assert rc == 3 and b'too_deep at "/bodies/0/nodes' in line and b"of part 0" in line, line
    (tmp_path / "part_1.json").unlink()
    rc, line = fault("--max-depth", "x")  # the flag before the parts (part 1 is gone)
    assert rc == 2 and b"--max-depth needs a positive count, not 'x'" in line, line
    # in the name of the program run (it said "ntscontact:" and "Try 'ntscontact --help'")
    got = subprocess.run(base + ["--max-depth", "x"], capture_output=True, timeout=300, env=ENV)
    assert got.stderr.splitlines()[:2] == [b"ntscontact-mpi: --max-depth needs a positive count, not 'x'",
                                           b"Try 'ntscontact-mpi --help' for more information."], got.stderr


def mpi_session_dir(path):
    """Open MPI's own session directory under `path`, apart from $TMPDIR:
    its names in Open MPI 4 (ORTE) and 5 (PRRTE), and PMIx's."""
    return {"OMPI_MCA_orte_tmpdir_base": str(path), "PRTE_MCA_prte_tmpdir_base": str(path),
            "PMIX_SYSTEM_TMPDIR": str(path)}


def test_part_assembled_in_tmpdir(tmp_path):
    """--part assembles the whole request in a temporary file under $TMPDIR
    when it is set (the user's, not always /tmp): a TMPDIR where no file can
    be made is named in the error, exit 1 (the CLI's for a failed write); a good one gives the answer of
    the whole scene and holds nothing afterwards."""
    scene = completed(packing(8, 22))
    (tmp_path / "whole.json").write_text(json.dumps(scene))
    for r, share in enumerate([scene["bodies"][:4], scene["bodies"][4:]]):
        (tmp_path / f"part_{r}.json").write_text(json.dumps(dict(scene, bodies=share)))
    cmd = [MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json")]
    # a TMPDIR no one can make (under a file; root makes a missing one), Open
    # MPI's own session directory kept apart from it
    (tmp_path / "a-file").write_text("")
    bad = tmp_path / "a-file" / "tmp"
    ompi = tmp_path / "ompi"
    ompi.mkdir()
    env = dict(ENV, TMPDIR=str(bad), **mpi_session_dir(ompi))
    got = subprocess.run(cmd, capture_output=True, timeout=300, env=env)
    assert got.returncode == 1 and got.stdout == b"", got.stderr.decode()
    assert f"cannot write the assembled request to {bad}/ntscontact-mpi-".encode() in got.stderr, got.stderr
    own = tmp_path / "tmp"
    own.mkdir()
    got = subprocess.run(cmd, capture_output=True, timeout=300, env=dict(ENV, TMPDIR=str(own)))
    one = subprocess.run([str(SERIAL), str(tmp_path / "whole.json")], capture_output=True, timeout=300)
    assert got.returncode == 0 and one.returncode == 0, got.stderr.decode()
    assert ELAPSED.sub(b"", got.stdout) == ELAPSED.sub(b"", one.stdout)
    assert list(own.iterdir()) == []


def test_part_stopped_by_ctrl_c_leaves_no_assembled_request(tmp_path):
    """Ctrl-C at mpirun (which sends its ranks SIGTERM) while the CLI runs
    on the assembled request: the temporary file goes with the run, as at a
    normal end; it was left in $TMPDIR. The CLI is held at a point where
    the file exists: opening -o, a FIFO that no one reads."""
    import signal
    import time

    scene = completed(packing(8, 22))
    for r, share in enumerate([scene["bodies"][:4], scene["bodies"][4:]]):
        (tmp_path / f"part_{r}.json").write_text(json.dumps(dict(scene, bodies=share)))
    own, ompi = tmp_path / "tmp", tmp_path / "ompi"
    own.mkdir()
    ompi.mkdir()
    fifo = tmp_path / "out.fifo"
    os.mkfifo(fifo)
    cmd = [MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json"),
           "-o", str(fifo)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=dict(ENV, TMPDIR=str(own), **mpi_session_dir(ompi)))
    try:
        deadline = time.monotonic() + 120  # (a bound, not a figure: the file appears once the parts are read)
        while not list(own.glob("ntscontact-mpi-*")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert list(own.glob("ntscontact-mpi-*")), "no assembled request while the CLI runs"
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode != 0
    assert list(own.glob("ntscontact-mpi-*")) == [], proc.stderr.read().decode() if proc.stderr else ""


def test_part_on_a_full_disk_says_so_and_leaves_nothing(tmp_path):
    """--part whose $TMPDIR fills up while the assembled request is written:
    exit 1 naming the file and the reason, and the file removed (the write's error flag,
    then the close that flushes the rest, both checked). The full disk is a
    small tmpfs; where mounting one is not allowed (not root, a container
    without the right) the test is skipped."""
    scene = completed(packing(8, 22))
    for r, share in enumerate([scene["bodies"][:4], scene["bodies"][4:]]):
        (tmp_path / f"part_{r}.json").write_text(json.dumps(dict(scene, bodies=share)))
    with full_disk(tmp_path / "full", "4k") as full:
        ompi = tmp_path / "ompi"
        ompi.mkdir()
        env = dict(ENV, TMPDIR=str(full), **mpi_session_dir(ompi))
        cmd = [MPIRUN, "-np", "2", "--oversubscribe", str(MPI_CLI), "--part", str(tmp_path / "part_%d.json")]
        got = subprocess.run(cmd, capture_output=True, timeout=300, env=env)
        assert got.returncode == 1 and got.stdout == b"", got.stderr.decode()
        assert f"cannot write the assembled request to {full}/ntscontact-mpi-".encode() in got.stderr, got.stderr
        assert b"No space left on device" in got.stderr, got.stderr
        assert list(full.iterdir()) == []
