"""`ntscontact --frames FRAMES.bin SCENE.json`: the scene parsed once, one
result line per frame of raw float64 positions, each equal to the one-shot
CLI on the full scene at those positions (elapsed_ms aside)."""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

from conftest import positions_of, with_positions

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"
EXAMPLES = ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"]


def run(*args, stdin=None):
    return subprocess.run([str(CLI), *map(str, args)], input=stdin, capture_output=True, timeout=120)




def without_elapsed(doc):
    doc["summary"].pop("elapsed_ms", None)
    return doc


def moves(scene, count, seed):
    pos0 = positions_of(scene)
    rng = np.random.default_rng(seed)
    return [pos0 + rng.normal(scale=1e-3, size=pos0.shape) for _ in range(count)]


@pytest.mark.parametrize("name", EXAMPLES)
def test_each_frame_equals_the_one_shot_cli(tmp_path, name):
    scene_path = REPO / "examples" / f"{name}.json"
    scene = json.loads(scene_path.read_text())
    frames = moves(scene, 3, len(name))
    path = tmp_path / "frames.bin"
    path.write_bytes(b"".join(f.astype("<f8").tobytes() for f in frames))
    r = run("--frames", path, "--outputs", "forces,contacts", scene_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.decode().splitlines()
    assert len(lines) == 3
    for line, pos in zip(lines, frames):
        one = tmp_path / "one.json"
        one.write_text(json.dumps(with_positions(scene, pos)))
        want = run("--outputs", "forces,contacts", one)
        assert want.returncode == 0
        assert without_elapsed(json.loads(line)) == without_elapsed(json.loads(want.stdout))
    # From standard input too, and to a file.
    out = tmp_path / "out.jsonl"
    r = run("--frames", "-", "-o", out, "--outputs", "forces,contacts", scene_path, stdin=path.read_bytes())
    assert r.returncode == 0, r.stderr
    assert [without_elapsed(json.loads(a)) for a in out.read_text().splitlines()] == \
           [without_elapsed(json.loads(a)) for a in lines]


def test_no_frames_no_lines(tmp_path):
    path = tmp_path / "empty.bin"
    path.write_bytes(b"")
    r = run("--frames", path, REPO / "examples" / "two_disks.json")
    assert r.returncode == 0 and r.stdout == b""


def test_bad_frames_name_the_frame(tmp_path):
    scene_path = REPO / "examples" / "two_disks.json"
    scene = json.loads(scene_path.read_text())
    n = len(positions_of(scene))
    frames = moves(scene, 3, 1)
    frames[1][17, 0] = np.nan
    path = tmp_path / "frames.bin"
    path.write_bytes(b"".join(f.astype("<f8").tobytes() for f in frames))
    r = run("--frames", path, scene_path)
    assert r.returncode == 3
    assert len(r.stdout.decode().splitlines()) == 1  # frame 0 was answered
    assert r.stderr.decode().startswith('ntscontact: frame 1: non_finite at "/positions/17": ')
    # A truncated last frame.
    path.write_bytes(frames[0].astype("<f8").tobytes() + b"\0" * 40)
    r = run("--frames", path, scene_path)
    assert r.returncode == 3
    assert "frame 1: invalid_value" in r.stderr.decode() and f"16 * {n}" in r.stderr.decode()
    # An invalid scene fails before any frame.
    bad = tmp_path / "bad.json"
    bad.write_text('{"options": {"penalty": 1}, "bodies": []}')
    r = run("--frames", path, bad)
    assert r.returncode == 3 and r.stderr.decode().startswith("ntscontact: empty_scene")
    # Usage errors.
    assert run("--frames", path, "--pretty", scene_path).returncode == 2
    assert run("--frames", path, "--validate", scene_path).returncode == 2
    assert run("--frames", "-", "-", stdin=b"").returncode == 2
    assert run("--frames", tmp_path / "missing.bin", scene_path).returncode == 2


def polygon(n, r, centre, phase=0.0):
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.c_[centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)]


def test_frames_do_not_depend_on_the_history(tmp_path):
    """Issue 22 §4 through --frames: with penalty per length, a frame that
    needs a new scene (a far body mirrored) used to measure the tributary
    lengths at its own positions, and every later frame kept them. The
    lengths belong to the scene file's positions: a frame's line is the
    one-shot CLI's with those positions as each body's "reference"."""
    a, b, c = polygon(24, 1.0, (0, 0)), polygon(20, 1.0, (1.9, 0.05), 0.1), polygon(12, 0.5, (10, 0))
    scene = {"version": 1, "options": {"penalty": 100.0, "penalty_scaling": "length", "search_radius": 0.3},
             "bodies": [{"id": "a", "nodes": a.tolist()}, {"id": "b", "nodes": b.tolist()},
                        {"id": "c", "nodes": c.tolist()}]}
    scene_path = tmp_path / "scene.json"
    scene_path.write_text(json.dumps(scene))
    p = np.vstack([1.5 * a, b + [0.55, 0.0], c])
    q = p.copy()
    q[44:, 0] = 20.0 - q[44:, 0]
    path = tmp_path / "frames.bin"
    path.write_bytes(b"".join(f.astype("<f8").tobytes() for f in (p, q, p)))
    r = run("--frames", path, "--outputs", "forces,contacts", scene_path)
    assert r.returncode == 0, r.stderr
    lines = [without_elapsed(json.loads(line)) for line in r.stdout.decode().splitlines()]
    assert len(lines) == 3 and lines[0]["summary"]["contacts"] > 0
    assert lines[1]["summary"]["loops_reversed"] == 1
    assert lines[1]["summary"]["energy"] == lines[0]["summary"]["energy"]
    assert lines[1]["contacts"] == lines[0]["contacts"]
    assert lines[2] == lines[0]
    for line, pos in zip(lines, (p, q, p)):
        one = with_positions(scene, pos)
        for body, start in zip(one["bodies"], scene["bodies"]):
            body["reference"] = start["nodes"]
        one_path = tmp_path / "one.json"
        one_path.write_text(json.dumps(one))
        want = run("--outputs", "forces,contacts", one_path)
        assert want.returncode == 0, want.stderr
        assert line == without_elapsed(json.loads(want.stdout))
