#!/usr/bin/env python3
"""Draw docs/img/scene.png: examples/triangle_meshes.json evaluated by the CLI,
drawn with ntscontact.plot (each corner smoothed by its body's alpha, contact
forces as arrows). Needs matplotlib and a build (build/bin/ntscontact)."""
import json
import os
import pathlib
import subprocess

import matplotlib

matplotlib.use("Agg")
import ntscontact  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"
scene = ntscontact.Scene.load(REPO / "examples" / "triangle_meshes.json")
out = subprocess.run([str(CLI), "--outputs", "forces", str(REPO / "examples" / "triangle_meshes.json")],
                     capture_output=True, check=True).stdout
result = ntscontact.Result.from_json(out)
ax = ntscontact.plot(scene, result)
ax.set_title("examples/triangle_meshes.json: smoothed contact surfaces and contact forces", fontsize=9)
path = pathlib.Path(__file__).with_suffix(".png")
ax.figure.savefig(path, dpi=100, bbox_inches="tight")
print(path)
