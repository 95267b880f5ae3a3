#!/usr/bin/env python3
"""Write the seeds of the fuzzer. fuzz/seeds/: hand-made scenes, small on
purpose (a few dozen nodes) so that libFuzzer mutates them quickly: every way
a body can be given (implicit loop, explicit loops with a hole, triangle mesh),
a clockwise body, a periodic box, both solvers, every output, string and
integer ids, contact surfaces, friction with a history. fuzz/corpus/cat-*.json: every case of the CLI's malformed
catalogue (tests/python/malformed/cases.json) given by its bytes (the
generated ones, a huge file and deep nesting, are left to the fuzzer).
Re-run after changing the contract or the catalogue; the files are committed."""
import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def disk(cx, cy, r, n, phase=0.0, digits=6):
    return [[round(cx + r * math.cos(2 * math.pi * i / n + phase), digits),
             round(cy + r * math.sin(2 * math.pi * i / n + phase), digits)] for i in range(n)]


def grid_mesh(x0, y0, h, nx, ny):
    nodes = [[x0 + h * i, y0 + h * j] for j in range(ny + 1) for i in range(nx + 1)]
    tris = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 2, a + nx + 1
            tris += [[a, b, c], [a, c, d]]
    return nodes, tris


def seeds():
    yield "two_disks", {
        "version": 1,
        "options": {"penalty": 100.0, "alpha": 0.2,
                    "outputs": ["forces", "energy", "virial", "contacts", "gaps"]},
        "bodies": [{"id": "a", "nodes": disk(0, 0, 1, 12)},
                   {"id": "b", "nodes": disk(1.95, 0, 1, 12, math.pi / 12)}]}
    yield "clockwise", {
        "version": 1,
        "options": {"penalty": 10.0, "solver": "newton", "outputs": ["forces", "contacts"]},
        "bodies": [{"id": 1, "nodes": disk(0, 0, 1, 10)},
                   {"id": 2, "nodes": disk(1.9, 0.1, 1, 10)[::-1]}]}
    ring = disk(0, 2.55, 0.8, 10) + disk(0, 2.55, 0.4, 8, 0.2)
    yield "hole_loops", {
        "version": 1,
        "options": {"penalty": 50.0, "search_radius": 0.3,
                    "outputs": ["forces", "energy", "virial", "gaps"]},
        "bodies": [{"id": "ring", "nodes": ring,
                    "loops": [list(range(10)), list(range(17, 9, -1))]},
                   {"id": "disk", "nodes": disk(0, 0.8, 1, 12)}]}
    nodes, tris = grid_mesh(-0.5, -2.45, 0.5, 2, 3)
    yield "mesh", {
        "version": 1,
        "options": {"penalty": 100.0, "alpha": 0.0, "outputs": ["forces", "contacts"]},
        "bodies": [{"id": "square", "nodes": nodes, "triangles": tris},
                   {"id": 7, "nodes": disk(0, 0, 1, 12)}]}
    bodies = []
    for k, (cx, cy) in enumerate([(1.0, 1.0), (2.9, 1.0), (1.0, 2.9), (2.9, 2.9)]):
        bodies.append({"id": "p%d" % k, "nodes": disk(cx % 4.0, cy % 4.0, 1.0, 8, 0.3 * k)})
    yield "periodic", {
        "version": 1,
        "options": {"penalty": 1.0, "alpha": 0.5, "search_radius": 0.2,
                    "periodic": {"lx": 7.6, "ly": 7.6},
                    "outputs": ["forces", "energy", "virial", "contacts", "gaps"]},
        "bodies": bodies}
    lower, _ = grid_mesh(0.0, 0.0, 0.25, 4, 1)
    upper = [[0.0, 0.24], [0.5, 0.24], [1.0, 0.24], [1.0, 0.74], [0.0, 0.74]]
    yield "surfaces", {
        "version": 1,
        "options": {"penalty": 100.0, "alpha": 0.2, "penalty_scaling": "length", "surface_extension": 0.01,
                    "outputs": ["forces", "energy", "contacts", "pressure"]},
        "bodies": [{"id": "lower", "nodes": lower, "loops": [[0, 1, 2, 3, 4, 9, 8, 7, 6, 5]],
                    "surface": [[9, 8], [8, 7], [6, 7], [5, 6]], "role": "master"},
                   {"id": "upper", "nodes": upper, "surface": [[0, 1], [1, 2]]}]}
    # friction with a history (docs/model.md §14): a segment, a corner and a
    # vertex anchor, a body's own coefficient, the tangent (not symmetric)
    yield "friction", {
        "version": 1,
        "options": {"penalty": 100.0, "alpha": 0.2, "friction": {"coefficient": 0.3, "tangential_penalty": 50.0},
                    "outputs": ["forces", "contacts", "stiffness"]},
        "bodies": [{"id": "flat", "nodes": [[-2, -1], [2, -1], [2, 0], [1, 0], [0, 0], [-1, 0], [-2, 0]],
                    "friction": 0.5},
                   {"id": 7, "nodes": [[-0.5, -0.01], [0, -0.01], [0.5, -0.01], [0.5, 1], [-0.5, 1]]}],
        "history": [{"slave": {"body": 7, "node": 0}, "master": "flat", "kind": "segment", "nodes": [4, 5],
                     "param": 0.49},
                    {"slave": {"body": 7, "node": 1}, "master": "flat", "kind": "corner", "nodes": [3, 4, 5],
                     "param": 0.1},
                    {"slave": {"body": "flat", "node": 4}, "master": 7, "kind": "vertex", "nodes": [1],
                     "param": 0.0}]}
    yield "minimal", {"version": 1, "options": {"penalty": 1},
                      "bodies": [{"id": 0, "nodes": [[0, 0], [1, 0], [0, 1]]}]}


def catalogue():
    path = os.path.join(HERE, "..", "tests", "python", "malformed", "cases.json")
    if not os.path.exists(path):
        return
    with open(path) as f:
        cases = json.load(f)["cases"]
    for case in cases:
        if "text" in case:
            data = case["text"].encode("utf-8")
        elif "text_latin1" in case:
            data = case["text_latin1"].encode("latin-1")
        elif "scene" in case:
            data = json.dumps(case["scene"], separators=(",", ":")).encode("utf-8")
        else:
            continue
        yield case["name"], data


def main():
    corpus = os.path.join(HERE, "corpus")
    os.makedirs(corpus, exist_ok=True)
    for name, data in catalogue():
        with open(os.path.join(corpus, "cat-%s.json" % name), "wb") as f:
            f.write(data)
    out = os.path.join(HERE, "seeds")
    os.makedirs(out, exist_ok=True)
    for name, scene in seeds():
        with open(os.path.join(out, name + ".json"), "w") as f:
            json.dump(scene, f, separators=(",", ":"))
            f.write("\n")


if __name__ == "__main__":
    main()
