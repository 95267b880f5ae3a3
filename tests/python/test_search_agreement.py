"""The cells and brute force give the same contacts (schemas/scene.schema.json:
"both give the same contacts"), bit for bit, on scenes where they once did
not: loops that cross themselves many times in a periodic box, found by a
random stress of kept candidate lists (2026-12-06). The deep contacts'
growth (docs/model.md §4.5) settles a point outside a body's circle or
bounding box as outside, whichever search asks, and the grid of the
bodies' boxes allows for a contact surface's extension as that test does.

- crossing_loops_1.json: 4 bodies; the cells' grid of boxes left out a body
  whose circle (none: it spans more than a quarter of the box) let brute
  force search it (11 against 13 contacts).
- crossing_loops_2.json: 16 bodies, self-contact, contact surfaces (ext
  0.29); the grid's boxes lacked the surfaces' extension (4 against 17).
"""
import json
import pathlib

import pytest

from conftest import run_cli_json

SCENES = pathlib.Path(__file__).resolve().parent / "scenes"


@pytest.mark.parametrize("name", ["crossing_loops_1.json", "crossing_loops_2.json"])
def test_cells_and_brute_force_agree(name):
    doc = json.loads((SCENES / name).read_text())
    doc["options"]["outputs"] = ["energy", "contacts", "forces"]
    cells = run_cli_json(dict(doc, options=dict(doc["options"], search="cells")))
    brute = run_cli_json(dict(doc, options=dict(doc["options"], search="brute_force")))
    assert cells["summary"]["deep_contacts"] > 0  # the deep contacts' growth is what is compared
    for key in ("contacts", "deep_contacts", "gaps", "energy", "virial", "max_penetration"):
        assert cells["summary"][key] == brute["summary"][key], key
    assert cells["contacts"] == brute["contacts"]
    assert cells["bodies"] == brute["bodies"]  # the forces, body by body
