"""Each vocabulary's table against the documents written by hand (issue 24 §3):
the options (NTS_OPTION_MAP, core/include/ntscontact/tables.h) against
scene.schema.json's options, session.schema.json's step overrides and the
query parameters of POST /v1/scenes/{id}/contact in openapi.json, and the
CLI's --help against the table. The error codes have the same test in
test_cli.py (test_error_codes_are_the_core_and_codec_tables)."""
import json
import re
import subprocess
from typing import Any, Dict

import pytest

import tables
from conftest import BUILD, REPO

CLI = BUILD / "bin" / "ntscontact"
OPTIONS = tables.options()
OPENAPI = json.loads((REPO / "schemas" / "openapi.json").read_text())


def c_number(text: str) -> float:
    return float(text)


def schema_of(row: Dict[str, str]) -> Dict[str, Any]:
    """What the table says of an option, in JSON Schema words (those it states)."""
    kind = row["kind"]
    out: Dict[str, Any] = {}
    if kind == "NUMBER":
        out["type"] = "number"
        lo, hi = c_number(row["min"]), c_number(row["max"])
        if row["bound"] == "CLOSED":
            out.update(minimum=lo, maximum=hi)
        elif row["bound"] == "ABOVE":
            out["exclusiveMinimum"] = lo
        elif row["bound"] == "FROM":
            out["minimum"] = lo
    elif kind == "ENUM":
        names = tables.enum_names(row["names"])
        out["enum"] = list(names.values())
        out["default"] = names[row["default"]]
    elif kind == "OUTPUTS":
        out["type"] = "array"
        out["default"] = [f.removeprefix("NTS_OUT_").lower() for f in re.split(r"\s*\|\s*", row["default"])]
    elif kind == "BOX":
        out["type"] = "object"
    return out


def test_the_table_is_read():
    assert [r["json"] for r in OPTIONS][:3] == ["alpha", "penalty", "search_radius"]
    assert len(OPTIONS) >= 8


def test_the_scene_schema_has_exactly_the_tables_options(schemas):
    props = schemas["scene"]["$defs"]["options"]["properties"]
    assert set(props) == {r["json"] for r in OPTIONS}
    required = set(schemas["scene"]["$defs"]["options"].get("required", []))
    assert required == {r["json"] for r in OPTIONS if r["presence"] == "REQUIRED"}


@pytest.mark.parametrize("row", OPTIONS, ids=lambda r: r["json"])
def test_each_option_has_the_schemas_type_default_and_range(schemas, row):
    prop = schemas["scene"]["$defs"]["options"]["properties"][row["json"]]
    want = schema_of(row)
    for key in ("type", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum", "enum"):
        if key in prop or key in want:
            assert prop.get(key) == want.get(key), (row["json"], key)
    if "default" in prop:  # the table's default where the schema states one
        assert want.get("default", c_number(row["default"]) if row["kind"] == "NUMBER" else None) == prop["default"]
    if row["kind"] == "NUMBER" and "default" in prop:
        assert c_number(row["default"]) == prop["default"]
    if row["kind"] == "OUTPUTS":
        assert prop["items"] == {"$ref": "#/$defs/output"}


def test_a_step_overrides_the_tables_step_options(schemas):
    step = {r["json"]: r for r in OPTIONS if r["doors"] == "ALL"}
    overrides = schemas["session"]["$defs"]["overrides"]["properties"]
    assert set(overrides) == set(step)
    scene = schemas["scene"]["$defs"]["options"]["properties"]
    for name, prop in overrides.items():
        want = schema_of(step[name])
        for key in ("type", "minimum", "maximum", "exclusiveMinimum", "enum"):
            if key in prop or (key in want and key != "type"):
                assert prop.get(key) == want.get(key), (name, key)
        if step[name]["kind"] != "OUTPUTS":
            assert {k: v for k, v in prop.items() if k not in ("description", "default")} == \
                {k: v for k, v in scene[name].items() if k not in ("description", "default")}


def test_a_binary_steps_query_parameters_are_the_tables_step_options():
    op = OPENAPI["paths"]["/v1/scenes/{id}/contact"]["post"]
    query = {p["name"]: p for p in op["parameters"] if p.get("in") == "query"}
    step = {r["json"]: r for r in OPTIONS if r["doors"] == "ALL"}
    assert set(query) == set(step)
    for name, p in query.items():
        want = schema_of(step[name])
        if step[name]["kind"] == "OUTPUTS":
            assert p["schema"] == {"type": "string"}  # comma-separated
            continue
        for key in ("type", "minimum", "maximum", "exclusiveMinimum", "enum"):
            assert p["schema"].get(key) == want.get(key), (name, key)


def test_the_cli_flags_are_the_tables_cli_options():
    text = subprocess.run([str(CLI), "--help"], capture_output=True, text=True, timeout=30).stdout
    listed = {flag: meta for flag, meta in re.findall(r"(?m)^  (--[a-z][a-z-]*) ([A-Z][A-Za-z.]*) ", text)}
    for row in OPTIONS:
        if row["doors"] != "ALL":
            assert row["flag"] == "" and f"--{row['json'].replace('_', '-')} " not in text
            continue
        assert row["flag"] == "--" + row["json"].replace("_", "-")
        assert listed.get(row["flag"]) == row["metavar"], row["flag"]
        line = text[text.index(f"  {row['flag']} "):]
        line = line[:line.index("\n")]
        assert row["metavar"] in line
        if row["kind"] == "ENUM":
            for name in tables.enum_names(row["names"]).values():
                assert name in line
        if row["bound"] == "CLOSED":
            assert f"[{c_number(row['min']):g}, {c_number(row['max']):g}]" in line


@pytest.mark.parametrize("row", [r for r in OPTIONS if r["doors"] == "ALL" and r["kind"] == "ENUM"],
                         ids=lambda r: r["json"])
def test_a_bad_enum_value_is_refused_at_every_door(row, tmp_path):
    names = list(tables.enum_names(row["names"]).values())
    proc = subprocess.run([str(CLI), row["flag"], "bogus", str(REPO / "examples" / "two_disks.json")],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2 and all(n in proc.stderr for n in names)
    scene = json.loads((REPO / "examples" / "two_disks.json").read_text())
    scene["options"][row["json"]] = "bogus"
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene))
    proc = subprocess.run([str(CLI), str(path)], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 3
    assert proc.stderr.startswith(f'ntscontact: invalid_value at "/options/{row["json"]}"')


# ------------------------------------------------------------------ outputs

OUTPUTS = tables.outputs()


def test_the_output_table_is_in_bit_order():
    assert [int(r["bit"]) for r in OUTPUTS] == list(range(len(OUTPUTS)))
    assert [r["name"] for r in OUTPUTS][:3] == ["forces", "energy", "virial"]


def test_the_schemas_output_names_are_the_tables(schemas):
    names = [r["name"] for r in OUTPUTS]
    assert schemas["scene"]["$defs"]["output"]["enum"] == names
    step = schemas["session"]["$defs"]["overrides"]["properties"]["outputs"]
    assert step["items"]["enum"] == names


def test_the_python_client_knows_the_tables_outputs():
    from ntscontact.scene import OUTPUTS as PY_OUTPUTS
    assert list(PY_OUTPUTS) == [r["name"] for r in OUTPUTS]


@pytest.mark.parametrize("row", OUTPUTS, ids=lambda r: r["name"])
def test_each_output_has_its_place_in_the_result_schema(schemas, row):
    defs = schemas["result"]["$defs"]
    node = defs["result"]
    for part in row["result"].split("/"):
        props = node.get("properties", {})
        assert part in props, (row["name"], row["result"])
        node = props[part]
        while "$ref" in node:
            node = defs[node["$ref"].split("/")[-1]]
        if node.get("type") == "array" and "items" in node and "properties" in node["items"]:
            node = node["items"]


@pytest.mark.parametrize("row", OUTPUTS, ids=lambda r: r["name"])
def test_each_output_is_answered_where_the_table_says(row):
    proc = subprocess.run([str(CLI), "--outputs", row["name"], str(REPO / "examples" / "two_disks.json")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    node: Any = doc
    for part in row["result"].split("/"):
        node = node[0] if isinstance(node, list) else node
        assert part in node, (row["name"], row["result"])
        node = node[part]
    # an output not asked for is not there (the summary's are always there)
    if not row["result"].startswith("summary/"):
        other = subprocess.run([str(CLI), "--outputs", "", str(REPO / "examples" / "two_disks.json")],
                               capture_output=True, text=True, timeout=60)
        top = row["result"].split("/")[0]
        if top == "bodies":
            assert all(row["result"].split("/")[1] not in b for b in json.loads(other.stdout).get("bodies", []))
        else:
            assert top not in json.loads(other.stdout)


def test_the_cli_help_lists_the_tables_outputs():
    text = subprocess.run([str(CLI), "--help"], capture_output=True, text=True, timeout=30).stdout
    assert "comma-separated: " + ",".join(r["name"] for r in OUTPUTS) in text
