"""The JSON contract and the one-shot CLI `ntscontact` (issue 3).

Every example validates against scene.schema.json and its output against
result.schema.json; the output's own numbers satisfy the contact model's
invariants (forces sum to zero and assemble from the contacts, the virial and
the energy are the sums over contacts); numbers round-trip; a catalogue of
malformed scenes (malformed/cases.json) each exits 3 with the expected code and
JSON pointer; a clockwise body is reversed and gives its twin's forces."""
import json
import math
import os
import re
import stat
import subprocess

import jsonschema
import numpy as np
import pytest

from conftest import BUILD, REPO, full_disk

CLI = BUILD / "bin" / "ntscontact"
# The scenes examples/make_examples.py writes (other files in examples/ are not ours to check).
EXAMPLE_NAMES = ("two_disks.json", "jittered_packing.json", "periodic_packing.json", "triangle_meshes.json")
EXAMPLES = [REPO / "examples" / name for name in EXAMPLE_NAMES]
CASES = json.loads((REPO / "tests" / "python" / "malformed" / "cases.json").read_text())["cases"]
ALL_OUTPUTS = "forces,energy,virial,contacts,gaps"
ERROR_LINE = re.compile(r'^ntscontact: ([a-z_]+) at "((?:[^"\\]|\\.)*)": (.+)$')

pytestmark = pytest.mark.skipif(not CLI.exists(), reason=f"{CLI} is not built (set NTS_BUILD_DIR)")


# ------------------------------------------------------------------ helpers

def run(*args, stdin=None, timeout=60):
    return subprocess.run([str(CLI), *map(str, args)], input=stdin, capture_output=True, timeout=timeout)


def evaluate(scene, *flags, tmp_path=None, warnings=()):
    """Run the CLI on a scene (a dict, or a path) and return the parsed result.
    Standard error must be empty, but for the lines of the `warnings` codes
    expected (each also in the result's "warnings")."""
    if isinstance(scene, dict):
        proc = run(*flags, "-", stdin=json.dumps(scene).encode())
    else:
        proc = run(*flags, scene)
    assert proc.returncode == 0, proc.stderr.decode()
    out = json.loads(proc.stdout)
    lines = proc.stderr.decode().splitlines()
    warned = out.get("warnings", [])  # (a validation report has none)
    assert {w["code"] for w in warned} <= set(warnings), warned
    assert len(lines) == len(warned), lines
    for line, w in zip(lines, warned):
        assert line == f"ntscontact: warning: {w['code']} ({w['count']}): {w['message']}"
    return out


def load(path):
    return json.loads(path.read_text())


def without_elapsed(result):
    result = json.loads(json.dumps(result))
    result["summary"].pop("elapsed_ms", None)
    return result


def disk(cx, cy, r, n, phase=0.0):
    return [[cx + r * math.cos(phase + 2 * math.pi * k / n), cy + r * math.sin(phase + 2 * math.pi * k / n)]
            for k in range(n)]


def two_disks(**options):
    opts = {"penalty": 100.0, "alpha": 0.2, "search_radius": 0.1, "outputs": ALL_OUTPUTS.split(",")}
    opts.update(options)
    return {"version": 1, "options": opts,
            "bodies": [{"id": "left", "nodes": disk(0.0, 0.0, 1.0, 24)},
                       {"id": 7, "nodes": disk(1.96, 0.02, 1.0, 24, phase=0.1)}]}


def pointer_get(doc, pointer):
    """Resolve an RFC 6901 pointer; KeyError/IndexError when it names nothing."""
    if pointer == "":
        return doc
    for token in pointer.split("/")[1:]:
        token = token.replace("~1", "/").replace("~0", "~")
        if isinstance(doc, list):
            if not re.fullmatch(r"0|[1-9][0-9]*", token):
                raise KeyError(token)
            doc = doc[int(token)]
        else:
            doc = doc[token]
    return doc


def boundary_nodes(triangles):
    """Nodes on directed edges whose reverse is absent (the mesh boundary)."""
    edges = set()
    for a, b, c in triangles:
        edges.update([(a, b), (b, c), (c, a)])
    return {n for (a, b) in edges if (b, a) not in edges for n in (a, b)}


# ------------------------------------------------------------------ schemas

@pytest.mark.parametrize("name", ["scene", "result", "error", "session"])
def test_schema_is_valid_2020_12(schemas, name):
    schema = schemas[name]
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["$id"] == f"https://ntscontact.dev/schemas/{name}.schema.json"


def schema_codes(error_schema):
    return {c for branch in error_schema["$defs"]["code"]["oneOf"] for c in branch["enum"]}


def test_error_codes_are_the_core_and_codec_tables(schemas):
    """error.schema.json lists exactly the core's NTS_ERRNO_MAP names plus the codec's NTSJ_CODE_MAP."""
    base_h = (REPO / "core" / "include" / "ntscontact" / "base.h").read_text()
    core = set(re.findall(r'XX\(\w+,\s*-\d+,\s*"([a-z_]+)"', base_h))
    codec_h = (REPO / "codec" / "include" / "ntscontact" / "codec.h").read_text()
    codec = set(re.findall(r'XX\([A-Z_]+,\s*"([a-z_]+)",\s*\d{3}\)', codec_h))
    assert len(core) >= 18 and len(codec) >= 15
    assert schema_codes(schemas["error"]) == core | codec
    # Every code the malformed catalogue expects is a stable code.
    assert {c["code"] for c in CASES} <= core | codec


# ------------------------------------------------------------------ examples

def test_there_are_bundled_examples():
    for p in EXAMPLES:
        assert p.exists()
        assert p.stat().st_size < 300_000


def test_examples_are_what_the_generator_writes(tmp_path):
    import sys
    subprocess.run([sys.executable, str(REPO / "examples" / "make_examples.py"), str(tmp_path)], check=True,
                   capture_output=True, timeout=60)
    generated = sorted(tmp_path.glob("*.json"))
    assert [p.name for p in generated] == sorted(EXAMPLE_NAMES)
    for p in generated:
        assert p.read_bytes() == (REPO / "examples" / p.name).read_bytes(), p.name


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_validates_against_scene_schema(schemas, path):
    jsonschema.validate(load(path), schemas["scene"], cls=jsonschema.Draft202012Validator)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_output_validates_and_satisfies_invariants(schemas, path):
    scene = load(path)
    result = evaluate(path, "--outputs", ALL_OUTPUTS)
    jsonschema.validate(result, schemas["result"], cls=jsonschema.Draft202012Validator)
    check_invariants(scene, result)
    # As the scene's own outputs asked: only those arrays.
    plain = evaluate(path)
    asked = set(scene["options"].get("outputs", ["forces", "energy", "virial"]))
    assert ("bodies" in plain) == ("forces" in asked)
    assert ("contacts" in plain) == ("contacts" in asked)
    assert ("gaps" in plain) == ("gaps" in asked)
    jsonschema.validate(plain, schemas["result"], cls=jsonschema.Draft202012Validator)


def check_invariants(scene, result):
    eps = scene["options"]["penalty"]
    radius = scene["options"]["search_radius"]
    s = result["summary"]
    bodies = scene["bodies"]
    ids = [b["id"] for b in bodies]
    index_of = {json.dumps(i): k for k, i in enumerate(ids)}

    # Echo: ids in order and type, one force per node sent.
    assert [b["id"] for b in result["bodies"]] == ids
    assert all(type(a) is type(b) for a, b in zip((b["id"] for b in result["bodies"]), ids))
    for sent, got in zip(bodies, result["bodies"]):
        assert len(got["forces"]) == len(sent["nodes"])
    assert s["bodies"] == len(bodies)
    assert s["nodes"] == sum(len(b["nodes"]) for b in bodies)
    assert s["search_radius"] == radius

    contacts, gaps = result["contacts"], result["gaps"]
    assert s["contacts"] == len(contacts) and s["gaps"] == len(gaps)
    assert len(contacts) > 0, "examples are meant to have active contacts"

    # Forces sum to zero.
    forces = [f for b in result["bodies"] for f in b["forces"]]
    scale = sum(abs(fx) + abs(fy) for fx, fy in forces)
    assert abs(sum(f[0] for f in forces)) <= 1e-12 * scale
    assert abs(sum(f[1] for f in forces)) <= 1e-12 * scale

    # Every contact: g < 0, unit normal, f = -eps g n, weights sum to one,
    # virial = eps g^2 n n; forces assemble from the contacts.
    assembled = [[[0.0, 0.0] for _ in b["nodes"]] for b in bodies]
    energy = 0.0
    vir = [0.0, 0.0, 0.0]
    for c in contacts:
        g, n, f = c["gap"], c["normal"], c["force"]
        assert g < 0 and -g <= radius
        assert abs(math.hypot(*n) - 1.0) < 1e-12
        assert f[0] == pytest.approx(-eps * g * n[0], rel=1e-12, abs=1e-12 * abs(eps * g))
        assert f[1] == pytest.approx(-eps * g * n[1], rel=1e-12, abs=1e-12 * abs(eps * g))
        m = c["master"]
        assert sum(m["weights"]) == pytest.approx(1.0, abs=1e-12)
        assert len(m["nodes"]) == {"segment": 2, "corner": 3, "vertex": 1}[m["kind"]]
        assert c["slave"]["body"] != m["body"]
        v = c["virial"]
        e2 = eps * g * g
        for key, want in (("xx", e2 * n[0] * n[0]), ("yy", e2 * n[1] * n[1]), ("xy", e2 * n[0] * n[1])):
            assert v[key] == pytest.approx(want, rel=1e-9, abs=1e-12 * e2)
        sb = index_of[json.dumps(c["slave"]["body"])]
        mb = index_of[json.dumps(m["body"])]
        assembled[sb][c["slave"]["node"]][0] += f[0]
        assembled[sb][c["slave"]["node"]][1] += f[1]
        for node, w in zip(m["nodes"], m["weights"]):
            assembled[mb][node][0] -= w * f[0]
            assembled[mb][node][1] -= w * f[1]
        energy += 0.5 * eps * g * g
        vir[0] += v["xx"]
        vir[1] += v["yy"]
        vir[2] += v["xy"]
    for want_body, got_body in zip(assembled, result["bodies"]):
        for want, got in zip(want_body, got_body["forces"]):
            assert got[0] == pytest.approx(want[0], rel=1e-9, abs=1e-12 * scale)
            assert got[1] == pytest.approx(want[1], rel=1e-9, abs=1e-12 * scale)

    # Energy is 1/2 eps sum g^2; the virial is the sum over contacts.
    assert s["energy"] == pytest.approx(energy, rel=1e-12)
    vscale = abs(s["virial"]["xx"]) + abs(s["virial"]["yy"])
    assert s["virial"]["xx"] == pytest.approx(vir[0], rel=1e-12, abs=1e-13 * vscale)
    assert s["virial"]["yy"] == pytest.approx(vir[1], rel=1e-12, abs=1e-13 * vscale)
    assert s["virial"]["xy"] == pytest.approx(vir[2], rel=1e-12, abs=1e-13 * vscale)
    assert s["max_penetration"] == max(-c["gap"] for c in contacts)

    # Gaps: every closest point within the radius; the active ones are the contacts.
    assert all(abs(g["gap"]) <= radius for g in gaps)
    active = sorted((json.dumps(g["slave"]), json.dumps(g["master"]["body"]), g["gap"]) for g in gaps if g["gap"] < 0)
    listed = sorted((json.dumps(c["slave"]), json.dumps(c["master"]["body"]), c["gap"]) for c in contacts)
    assert active == listed

    # Interior nodes of triangle meshes get exactly zero force.
    for sent, got in zip(bodies, result["bodies"]):
        if "triangles" in sent:
            surface = boundary_nodes(sent["triangles"])
            assert len(surface) < len(sent["nodes"])
            for k, f in enumerate(got["forces"]):
                if k not in surface:
                    assert f == [0.0, 0.0]


def test_triangle_mesh_with_hole_has_two_loops():
    scene = load(REPO / "examples" / "triangle_meshes.json")
    ring = scene["bodies"][0]
    assert ring["id"] == "ring"
    out = evaluate({"version": 1, "options": scene["options"], "bodies": [ring]}, "--validate")
    assert out["valid"] is True
    assert out["summary"]["surface_nodes"] == len(boundary_nodes(ring["triangles"]))
    assert out["summary"]["nodes"] == len(ring["nodes"])


def test_periodic_translation_by_a_box_period_gives_the_same_forces():
    scene = load(REPO / "examples" / "periodic_packing.json")
    lx, ly = scene["options"]["periodic"]["lx"], scene["options"]["periodic"]["ly"]
    base = evaluate(scene, "--outputs", "forces,contacts")
    moved = json.loads(json.dumps(scene))
    for k, b in enumerate(moved["bodies"]):
        sx, sy = (k % 3 - 1) * lx, (k % 2) * ly  # each body by its own whole number of periods
        b["nodes"] = [[x + sx, y + sy] for x, y in b["nodes"]]
    out = evaluate(moved, "--outputs", "forces,contacts")
    assert out["summary"]["contacts"] == base["summary"]["contacts"]
    assert out["summary"]["energy"] == pytest.approx(base["summary"]["energy"], rel=1e-9)
    for b0, b1 in zip(base["bodies"], out["bodies"]):
        for f0, f1 in zip(b0["forces"], b1["forces"]):
            assert f1 == pytest.approx(f0, rel=1e-7, abs=1e-9)
    # Contacts across the wrap exist: some slave and master centres are more than half a box apart.
    centres = {b["id"]: (sum(x for x, _ in b["nodes"]) / len(b["nodes"]), sum(y for _, y in b["nodes"]) / len(b["nodes"]))
               for b in scene["bodies"]}
    across = [c for c in base["contacts"]
              if abs(centres[c["slave"]["body"]][0] - centres[c["master"]["body"]][0]) > lx / 2
              or abs(centres[c["slave"]["body"]][1] - centres[c["master"]["body"]][1]) > ly / 2]
    assert across


# ------------------------------------------------------------------ numbers

def test_echoed_doubles_read_back_bitwise():
    """The search radius is echoed in the summary: awkward doubles come back exactly."""
    import random
    rng = random.Random(3)
    values = [0.1 + 0.2, 1.0 / 3.0, 0.1, 2.0 ** -30, 0.07000000000000001, 5e-324 * 2 ** 60]
    values += [rng.uniform(0.01, 0.3) for _ in range(6)]
    for v in values:
        # (radii this small leave the deepest contacts out, and say so)
        out = evaluate(two_disks(search_radius=v, outputs=[]), warnings=("penetration_beyond_radius",))
        assert out["summary"]["search_radius"] == v
        assert out["summary"]["search_radius"].hex() == v.hex()


def test_output_numbers_are_finite_reals_in_shortest_form():
    """Every number is printed with the shortest digits that read back
    bitwise, the nearest of that length: Python's repr gives the same
    digits (David Gay's shortest), number by number. (Grisu2, the printer
    before, gave one digit more for about 1 number in 1,000: the packing's
    output held 0.28002863140719497 for 0.280028631407195.)"""
    proc = run("--outputs", ALL_OUTPUTS, REPO / "examples" / "jittered_packing.json")
    text = proc.stdout.decode()
    assert "NaN" not in text and "Infinity" not in text and "nan" not in text and "inf" not in text
    tokens = re.findall(r'(?<=[\[,:])\s*(-?\d[0-9.eE+-]*)', text)
    reals = [t.strip() for t in tokens if re.search(r"[.eE]", t)]
    assert len(reals) > 1000

    def significant(t):
        return re.sub(r"[^0-9]", "", t.split("e")[0]).lstrip("0").rstrip("0") or "0"

    for t in reals:
        v = float(t)
        assert significant(t) == significant(repr(v)), (t, repr(v))


def test_doubling_the_penalty_doubles_every_force_exactly():
    """Scaling by 2 is exact in binary, so any digit lost in printing would show."""
    path = REPO / "examples" / "jittered_packing.json"
    eps = load(path)["options"]["penalty"]
    one = evaluate(path, "--outputs", "forces,contacts")
    two = evaluate(path, "--outputs", "forces,contacts", "--penalty", repr(2 * eps))
    assert two["summary"]["energy"] == 2 * one["summary"]["energy"]
    for key in ("xx", "yy", "xy"):
        assert two["summary"]["virial"][key] == 2 * one["summary"]["virial"][key]
    for b1, b2 in zip(one["bodies"], two["bodies"]):
        assert b2["forces"] == [[2 * fx, 2 * fy] for fx, fy in b1["forces"]]
    assert [c["gap"] for c in two["contacts"]] == [c["gap"] for c in one["contacts"]]


def test_integer_and_string_ids_echo_exactly():
    scene = two_disks(outputs=["forces", "contacts"])
    scene["bodies"][0]["id"] = 2 ** 53 - 1
    scene["bodies"][1]["id"] = "cellule-\u00e9t\u00e9 \"7\"/\\"
    out = evaluate(scene)
    assert out["bodies"][0]["id"] == 2 ** 53 - 1 and isinstance(out["bodies"][0]["id"], int)
    assert out["bodies"][1]["id"] == scene["bodies"][1]["id"]
    assert {json.dumps(c["slave"]["body"]) for c in out["contacts"]} == {json.dumps(b["id"]) for b in scene["bodies"]}
    scene["bodies"][0]["id"] = -3
    scene["bodies"][1]["id"] = 3
    out = evaluate(scene)
    assert [b["id"] for b in out["bodies"]] == [-3, 3]


def test_same_input_gives_the_same_bytes():
    path = REPO / "examples" / "periodic_packing.json"
    a = run("--outputs", ALL_OUTPUTS, path).stdout
    b = run("--outputs", ALL_OUTPUTS, path).stdout
    strip = re.compile(rb'"elapsed_ms":[^,}]*')
    assert strip.sub(b"", a) == strip.sub(b"", b)


# ------------------------------------------------------------------ orientation

def test_clockwise_body_is_reversed_and_gives_the_same_forces():
    ccw = two_disks()
    nodes = ccw["bodies"][1]["nodes"]
    n = len(nodes)
    base = evaluate(ccw)
    assert base["summary"]["loops_reversed"] == 0

    # Same nodes, loop given clockwise: forces bitwise equal.
    cw_loop = json.loads(json.dumps(ccw))
    cw_loop["bodies"][1]["loops"] = [[0] + list(range(n - 1, 0, -1))]
    out = evaluate(cw_loop)
    assert out["summary"]["loops_reversed"] == 1
    assert out["bodies"] == base["bodies"]
    assert out["summary"]["energy"] == base["summary"]["energy"]

    # Nodes themselves in clockwise order: forces equal node by node.
    order = [0] + list(range(n - 1, 0, -1))
    cw_nodes = json.loads(json.dumps(ccw))
    cw_nodes["bodies"][1]["nodes"] = [nodes[k] for k in order]
    out = evaluate(cw_nodes)
    assert out["summary"]["loops_reversed"] == 1
    assert out["summary"]["contacts"] == base["summary"]["contacts"]
    assert out["summary"]["energy"] == pytest.approx(base["summary"]["energy"], rel=1e-12)
    got = out["bodies"][1]["forces"]
    for pos, k in enumerate(order):
        assert got[pos] == pytest.approx(base["bodies"][1]["forces"][k], rel=1e-12, abs=1e-12)
    for f1, f0 in zip(out["bodies"][0]["forces"], base["bodies"][0]["forces"]):
        assert f1 == pytest.approx(f0, rel=1e-12, abs=1e-12)


# ------------------------------------------------------------------ options

def test_outputs_select_the_arrays():
    scene = two_disks()
    # (the summary and the warnings are always there)
    assert set(evaluate(scene, "--outputs", "")) == {"version", "summary", "warnings"}
    assert set(evaluate(scene, "--outputs", "forces")) == {"version", "summary", "warnings", "bodies"}
    assert set(evaluate(scene, "--outputs", "contacts,gaps")) == {"version", "summary", "warnings", "contacts", "gaps"}
    full = evaluate(scene, "--outputs", "")
    assert full["summary"]["energy"] > 0 and full["summary"]["contacts"] > 0  # summary always complete


def test_command_line_options_override_the_scene():
    scene = two_disks(alpha=0.2)
    edited = two_disks(alpha=0.1, solver="newton", search_radius=0.15)
    a = evaluate(scene, "--alpha", "0.1", "--solver", "newton", "--search-radius=0.15")
    b = evaluate(edited)
    assert without_elapsed(a) == without_elapsed(b)
    assert without_elapsed(a) != without_elapsed(evaluate(scene))


def test_penalty_on_the_command_line_completes_a_scene_without_one():
    scene = two_disks()
    del scene["options"]["penalty"]
    proc = run("-", stdin=json.dumps(scene).encode())
    assert proc.returncode == 3 and b"missing_field" in proc.stderr
    out = evaluate(scene, "--penalty", "100")
    assert without_elapsed(out) == without_elapsed(evaluate(two_disks()))


def test_out_of_range_override_is_invalid_input():
    proc = run("--alpha", "0.9", "-", stdin=json.dumps(two_disks()).encode())
    assert proc.returncode == 3
    m = ERROR_LINE.match(proc.stderr.decode().strip())
    assert m and m.group(1) == "invalid_option" and m.group(2) == "/options/alpha"


def test_solvers_agree():
    a = evaluate(two_disks(solver="closed_form"))
    b = evaluate(two_disks(solver="newton"))
    assert a["summary"]["contacts"] == b["summary"]["contacts"]
    for c0, c1 in zip(a["contacts"], b["contacts"]):
        assert c1["gap"] == pytest.approx(c0["gap"], rel=1e-9, abs=1e-14)


def test_cell_search_equals_brute_force():
    for path in EXAMPLES:
        scene = load(path)
        scene["options"]["outputs"] = ALL_OUTPUTS.split(",")
        cells = evaluate(dict(scene, options=dict(scene["options"], search="cells")))
        brute = evaluate(dict(scene, options=dict(scene["options"], search="brute_force")))
        for r in (cells, brute):
            r["summary"].pop("elapsed_ms")
            r["summary"].pop("cell_size")
        assert cells == brute, path.name


# ------------------------------------------------------------------ CLI

def cmake_version():
    """The version, written once: VERSION, which the top CMakeLists.txt reads."""
    assert "file(STRINGS \"${CMAKE_CURRENT_SOURCE_DIR}/VERSION\" NTS_VERSION" in (REPO / "CMakeLists.txt").read_text()
    return (REPO / "VERSION").read_text().strip()


def test_the_python_package_has_the_projects_version():
    init = (REPO / "clients" / "python" / "src" / "ntscontact" / "__init__.py").read_text()
    assert re.search(r'__version__ = "([^"]+)"', init).group(1) == cmake_version()


def test_help_and_version():
    proc = run("--help")
    assert proc.returncode == 0 and b"usage: ntscontact" in proc.stdout
    for flag in (b"--alpha", b"--penalty", b"--search-radius", b"--solver", b"--outputs", b"--pretty",
                 b"--validate", b"-o"):
        assert flag in proc.stdout
    version = cmake_version()
    proc = run("--version")
    assert proc.returncode == 0 and proc.stdout.decode().strip() == f"ntscontact {version}"


@pytest.mark.parametrize("args", [
    [],
    ["--bogus", "x.json"],
    ["--alpha"],
    ["--alpha", "abc", "examples/two_disks.json"],
    ["--penalty", "1e999", "examples/two_disks.json"],
    ["--solver", "bisection", "examples/two_disks.json"],
    ["--outputs", "forces,torques", "examples/two_disks.json"],
    ["--outputs", "forces,", "examples/two_disks.json"],
    ["examples/two_disks.json", "examples/jittered_packing.json"],
    ["/nonexistent/scene.json"],
    ["-o", "/nonexistent/dir/out.json", "examples/two_disks.json"],
], ids=lambda a: " ".join(a) or "no-args")
def test_usage_errors_exit_2(args):
    proc = subprocess.run([str(CLI), *args], capture_output=True, cwd=REPO, timeout=30)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == b""
    assert proc.stderr.startswith(b"ntscontact: ")


def test_stdin_file_and_output_file_agree(tmp_path):
    path = REPO / "examples" / "two_disks.json"
    from_file = run(path)
    from_stdin = run("-", stdin=path.read_bytes())
    out = tmp_path / "result.json"
    to_file = run("-o", out, path)
    to_file2 = run(f"--output={tmp_path / 'r2.json'}", path)
    to_stdout = run("-o", "-", path)
    assert to_stdout.returncode == 0 and to_stdout.stdout.startswith(b'{"version":1,')
    assert from_file.returncode == from_stdin.returncode == to_file.returncode == to_file2.returncode == 0
    assert to_file.stdout == b"" and to_file2.stdout == b""
    strip = re.compile(rb'"elapsed_ms":[^,}]*')
    texts = [from_file.stdout, from_stdin.stdout, out.read_bytes(), (tmp_path / "r2.json").read_bytes()]
    assert len({strip.sub(b"", t) for t in texts}) == 1
    assert from_file.stdout.endswith(b"}\n") and from_file.stdout.count(b"\n") == 1


def test_pretty_output_has_the_same_values():
    path = REPO / "examples" / "triangle_meshes.json"
    compact = run("--outputs", ALL_OUTPUTS, path).stdout
    pretty = run("--outputs", ALL_OUTPUTS, "--pretty", path).stdout
    assert pretty.count(b"\n") > 50
    assert without_elapsed(json.loads(pretty)) == without_elapsed(json.loads(compact))


def test_validate_reports_the_scene(schemas):
    for path in EXAMPLES:
        proc = run("--validate", path)
        assert proc.returncode == 0, proc.stderr
        report = json.loads(proc.stdout)
        jsonschema.validate(report, schemas["result"], cls=jsonschema.Draft202012Validator)
        assert report["valid"] is True and "contacts" not in report["summary"]
        full = evaluate(path)
        for key in ("bodies", "nodes", "surface_nodes", "loops_reversed"):
            assert report["summary"][key] == full["summary"][key]


# ------------------------------------------------------------------ malformed

def case_bytes(case, tmp_path):
    if "text" in case:
        return case["text"].encode("utf-8")
    if "text_latin1" in case:
        return case["text_latin1"].encode("latin-1")
    if "scene" in case:
        return json.dumps(case["scene"]).encode()
    kind, depth = case["generate"], case.get("depth", 0)
    if kind == "deep_nodes":
        return (b'{"version":1,"options":{"penalty":1},"bodies":[{"id":"a","nodes":'
                + b"[" * depth + b"]" * depth + b"}]}")
    if kind == "deep_root_field":
        return b'{"x":' + b"[" * depth + b"]" * depth + b"}"
    if kind == "huge":
        head = b'{"version":1,"options":{"penalty":1},"bodies":[{"id":"a","nodes":[[0,0],[1,0],[1,1]]}]}'
        return head + b" " * (case["bytes"] - len(head))
    raise ValueError(kind)


def test_catalogue_is_large_and_names_are_unique():
    assert len(CASES) >= 30
    assert len({c["name"] for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_malformed_scene_exits_3_with_code_and_pointer(schemas, case, tmp_path):
    data = case_bytes(case, tmp_path)
    path = tmp_path / "scene.json"
    path.write_bytes(data)
    first = None
    for flags in ([], ["--validate"]):
        proc = run(*flags, path)
        assert proc.returncode == 3, (proc.returncode, proc.stderr)  # never a crash (negative = signal)
        assert proc.stdout == b""
        lines = proc.stderr.decode("utf-8").splitlines()
        assert len(lines) == 1, lines
        m = ERROR_LINE.match(lines[0])
        assert m, lines[0]
        assert m.group(1) == case["code"], lines[0]
        assert json.loads(f'"{m.group(2)}"') == case["pointer"], lines[0]
        first = first or lines[0]
    # A pointer names a value that exists, unless the fault is a missing or
    # unreadable one.
    if case["code"] not in ("missing_field", "invalid_json", "too_deep", "payload_too_large", "empty_body"):
        doc = json.loads(data)
        pointer_get(doc, case["pointer"])
    # The stdin path answers alike (the huge case stops reading at the limit).
    if case.get("generate") != "huge":
        proc = run("-", stdin=data)
        assert proc.returncode == 3 and proc.stderr.decode().splitlines()[0] == first


SCHEMA_CODES = {"invalid_type", "missing_field", "unknown_field", "invalid_value", "invalid_option",
                "empty_scene", "no_nodes", "loop_too_short"}
# Faults with one of those codes that only the codec can see: a geometric
# rule (the implicit loop of a body with 2 nodes), a count across two fields
# (one reference point per node).
NOT_SCHEMA = {"two_node_body", "reference_of_another_length"}


@pytest.mark.parametrize("case", [c for c in CASES if "scene" in c], ids=lambda c: c["name"])
def test_schema_and_codec_agree_on_malformed_scenes(schemas, case):
    """What the scene schema can express, it rejects too; what it cannot, the codec still does."""
    validator = jsonschema.Draft202012Validator(schemas["scene"])
    errors = list(validator.iter_errors(case["scene"]))
    if case["code"] in SCHEMA_CODES and case["name"] not in NOT_SCHEMA:
        assert errors, f'{case["name"]}: the schema accepts what the codec rejects as {case["code"]}'
    elif case["code"] in ("duplicate_id", "index_out_of_range", "degenerate_segment", "zero_area_loop",
                          "zero_angle_spike", "node_in_two_loops", "non_manifold_mesh", "degenerate_triangle",
                          "box_too_small") and case["name"] not in ("loop_index_negative",):
        assert not errors, f'{case["name"]}: expected schema-valid, got {errors[0].message}'


# ------------------------------------------------------------------ output files

TWO_DISKS = REPO / "examples" / "two_disks.json"


def test_a_failed_side_file_leaves_the_result_file_as_it_was(tmp_path):
    """-o FILE with a --vtk or --history-out that cannot be made: exit 2
    naming it, and FILE as it was (it was emptied: cut before the side files
    were written); a FILE that was not there is not left behind empty. A
    FILE that cannot be opened stops the run before any side file."""
    keep = tmp_path / "keep.json"
    for flag, name in (("--vtk", "x.vtu"), ("--history-out", "h.json")):
        keep.write_text('{"precious": 1}')
        bad = tmp_path / "no_such_dir" / name
        got = run("-o", keep, flag, bad, TWO_DISKS)
        assert got.returncode == 2 and f"cannot write '{bad}'".encode() in got.stderr, got.stderr
        assert keep.read_text() == '{"precious": 1}'
        got = run("-o", tmp_path / "new.json", flag, bad, TWO_DISKS)
        assert got.returncode == 2 and not (tmp_path / "new.json").exists()
    (tmp_path / "side.vtu").write_text("old")
    got = run("-o", tmp_path / "no_such_dir" / "r.json", "--vtk", tmp_path / "side.vtu", TWO_DISKS)
    assert got.returncode == 2 and (tmp_path / "side.vtu").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.json", "side.vtu"]


def test_outputs_go_where_they_point(tmp_path):
    """-o through a symlink writes its target (the link stays a link); -o of
    a FIFO or /dev/null writes to it; a directory is a usage error."""
    target = tmp_path / "target.json"
    target.write_text("old")
    (tmp_path / "link.json").symlink_to(target)
    got = run("-o", tmp_path / "link.json", TWO_DISKS)
    assert got.returncode == 0 and (tmp_path / "link.json").is_symlink()
    assert json.loads(target.read_text())["summary"]["contacts"] > 0
    assert run("-o", "/dev/null", TWO_DISKS).returncode == 0
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    reader = subprocess.Popen(["cat", str(fifo)], stdout=subprocess.PIPE)
    got = run("-o", fifo, TWO_DISKS)
    out, _ = reader.communicate(timeout=60)
    assert got.returncode == 0 and json.loads(out)["summary"]["contacts"] > 0 and stat.S_ISFIFO(fifo.stat().st_mode)
    got = run("-o", tmp_path, TWO_DISKS)
    assert got.returncode == 2 and b"cannot write" in got.stderr


def test_two_outputs_in_one_file_are_refused(tmp_path):
    """-o and --vtk (or --history-out) naming one file, by the same name,
    through a link, or as two spellings of a file not made yet: a usage
    error, nothing written (the result was written over the start of the
    VTU, exit 0)."""
    same = tmp_path / "same.vtu"
    got = run("-o", same, "--vtk", same, TWO_DISKS)
    assert got.returncode == 2 and b"-o and --vtk name the same file" in got.stderr
    assert not same.exists()
    (tmp_path / "h.json").write_text("{}")
    (tmp_path / "link.json").symlink_to(tmp_path / "h.json")
    got = run("--history-out", tmp_path / "h.json", "-o", tmp_path / "link.json", TWO_DISKS)
    assert got.returncode == 2 and b"name the same file" in got.stderr
    assert (tmp_path / "h.json").read_text() == "{}"
    got = run("-o", tmp_path / "r.json", "--history-out", tmp_path / "." / "r.json", TWO_DISKS)
    assert got.returncode == 2 and b"name the same file" in got.stderr and not (tmp_path / "r.json").exists()


def test_frames_stream_and_say_where_they_stopped(tmp_path):
    """--frames -o FILE writes a line a frame as it goes: a refused second
    frame leaves the first line and exits 3 naming the frame (the status
    says the run stopped); a run that completes writes every line, with the
    permissions a new file gets (0666 less the umask); a standard output
    that cannot be written is exit 1 with the reason."""
    scene = json.loads(TWO_DISKS.read_text())
    x = np.concatenate([np.asarray(b["nodes"], float) for b in scene["bodies"]])
    bad = np.stack([x, x + 1e-4, x])
    bad[1][3, 0] = np.nan
    bad.astype("<f8").tofile(tmp_path / "bad.bin")
    np.stack([x, x + 1e-4]).astype("<f8").tofile(tmp_path / "ok.bin")
    out = tmp_path / "res.jsonl"
    got = run("--frames", tmp_path / "bad.bin", "-o", out, TWO_DISKS)
    assert got.returncode == 3 and b"frame 1: non_finite" in got.stderr
    assert len(out.read_text().splitlines()) == 1
    got = run("--frames", tmp_path / "ok.bin", "-o", out, TWO_DISKS)
    assert got.returncode == 0 and len(out.read_text().splitlines()) == 2
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~mask
    with open("/dev/full", "wb") as full:
        for flags in ((REPO / "examples" / "jittered_packing.json",), (TWO_DISKS,),
                      ("--frames", tmp_path / "ok.bin", TWO_DISKS)):
            got = subprocess.run([str(CLI), *map(str, flags)], stdout=full, stderr=subprocess.PIPE, timeout=60)
            assert got.returncode == 1 and b"error writing 'standard output': No space left" in got.stderr, got.stderr


def test_a_full_disk_is_a_failed_write_and_leaves_nothing(tmp_path):
    """-o, --vtk or --history-out on a full file system (a small tmpfs;
    skipped where one cannot be mounted): exit 1 with the system's reason,
    and no partial file left."""
    with full_disk(tmp_path / "full") as full:
        for flags in (["-o", full / "out.json", "--outputs", "forces,contacts,gaps,stiffness"],
                      ["--vtk", full / "x.vtu", "-o", tmp_path / "o.json"]):
            got = run(*flags, TWO_DISKS)
            assert got.returncode == 1 and b"No space left on device" in got.stderr, got.stderr
            assert list(full.iterdir()) == []
