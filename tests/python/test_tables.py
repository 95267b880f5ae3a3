"""Each vocabulary's table against the documents written by hand (issue 24 §3):
the options (NTS_OPTION_MAP, core/include/ntscontact/tables.h) against
scene.schema.json's options, session.schema.json's step overrides and the
query parameters of POST /v1/scenes/{id}/contact in openapi.json, and the
CLI's --help against the table; the daemon's routes (NTSD_ROUTE_MAP,
server/src/routes.h) against openapi.json's paths and operations, the Python
client's requests, and what a running daemon answers (Allow, 401, 404) and
counts in GET /metrics. The error codes have the same test in
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
    elif kind == "OBJECT":
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
    # commit (friction's history, docs/model.md §14) is a query parameter but not an option
    assert query.pop("commit")["schema"] == {"enum": ["true", "false"]}
    # nodes (a surface exchange: which nodes' positions and forces travel) neither
    assert query.pop("nodes")["schema"] == {"enum": ["all", "surface"]}
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


# ------------------------------------------------------------------ routes

ROUTES = tables.routes()
# The metrics label of a route is its path template, but for the two asset
# paths: both count as "/v1/schemas", as before the table (dashboards keep
# their series). Written here by hand, apart from the table.
SHARED_LABELS = {"/v1/openapi.json": "/v1/schemas", "/v1/schemas/{name}": "/v1/schemas"}
SID = "A" * 43  # a well-formed session id (none such is held)


def deref(node: Dict[str, Any]) -> Dict[str, Any]:
    while "$ref" in node:
        ref = node["$ref"].removeprefix("#/").split("/")
        node = OPENAPI
        for part in ref:
            node = node[part]
    return node


def operations(methods: str) -> set:
    """The OpenAPI operations of an Allow list: HEAD is not one (the server
    answers it wherever GET is, as HTTP says), and OPTIONS is not in the table."""
    return {m.strip().lower() for m in methods.split(",")} - {"head"}


def example_path(pattern: str) -> str:
    return pattern.replace("{id}", SID).replace("{name}", "scene")


def test_the_route_table_is_read():
    assert [r["pattern"] for r in ROUTES][:2] == ["/v1/contact", "/v1/validate"]
    assert len({r["id"] for r in ROUTES}) == len(ROUTES) == len({r["pattern"] for r in ROUTES})


def test_openapi_has_exactly_the_tables_routes_and_methods():
    table = {(r["pattern"], op) for r in ROUTES for op in operations(r["methods"])}
    spec = {(path, op) for path, item in OPENAPI["paths"].items() for op in item if op != "parameters"}
    assert table == spec, {"only in the table": table - spec, "only in openapi.json": spec - table}


@pytest.mark.parametrize("row", ROUTES, ids=lambda r: r["pattern"])
def test_each_route_keeps_the_servers_conventions(row):
    methods = [m.strip() for m in row["methods"].split(",")]
    assert "OPTIONS" not in methods  # added to Allow by the server, for the preflight
    assert ("GET" in methods) == ("HEAD" in methods)
    assert row["body"] == "NONE" or methods == ["POST"]  # a body is read by POST routes only
    assert row["label"] == SHARED_LABELS.get(row["pattern"], row["pattern"])


@pytest.mark.parametrize("row", ROUTES, ids=lambda r: r["pattern"])
def test_each_routes_body_and_path_parameter_are_openapis(row):
    item = OPENAPI["paths"][row["pattern"]]
    for op in operations(row["methods"]):
        body = deref(item[op]["requestBody"]) if "requestBody" in item[op] else None
        types = set(body["content"]) if body else set()
        assert types == {"NONE": set(), "JSON": {"application/json"},
                         "STEP": {"application/json", "application/octet-stream"}}[row["body"]], (op, types)
        if row["body"] == "JSON":
            assert body.get("required") is True  # the server refuses a JSON route's request without one
        params = [deref(p) for p in item.get("parameters", []) + item[op].get("parameters", [])]
        in_path = {p["name"] for p in params if p["in"] == "path"}
        assert in_path == set(re.findall(r"\{(\w+)\}", row["pattern"])), op
        assert (row["param"] != "NONE" and row["param"] != "OPENAPI") == bool(in_path)


@pytest.mark.parametrize("row", ROUTES, ids=lambda r: r["pattern"])
def test_each_routes_access_answers_are_openapis(row):
    """A route that needs the token (the table's auth column) declares 401,
    every route 403 (a refused Origin or Host), and the document says how
    the token is given (a generated client learns it from `security`)."""
    assert OPENAPI["security"] == [{}, {"bearer": []}]  # none, or the bearer token with --token-file
    assert OPENAPI["components"]["securitySchemes"]["bearer"]["scheme"] == "bearer"
    for op in operations(row["methods"]):
        codes = set(OPENAPI["paths"][row["pattern"]][op]["responses"])
        assert ("401" in codes) == (row["auth"] == "TOKEN"), op
        assert "403" in codes, op


def test_the_python_client_uses_the_tables_routes():
    src = "".join((REPO / "clients/python/src/ntscontact" / f).read_text() for f in ("client.py", "session.py"))
    used = re.findall(r'_request\(\s*"([A-Z]+)",\s*f?"([^"]+)"', src)
    assert len(used) >= 8
    for method, path in used:
        pattern = re.sub(r"\{self\.id\}", "{id}", path)
        rows = [r for r in ROUTES if r["pattern"] == pattern]
        assert rows and method in rows[0]["methods"], (method, path)


def test_the_daemon_routes_as_the_table_says(paths, tmp_path):
    """Each row's path, from a running daemon with a token: a method it does
    not take gets 405 with the row's Allow; no token gets 401 unless the row
    is OPEN; the schemas openapi.json names are served, and no other name.
    Then GET /metrics counts each row under its label, and no route else."""
    import requests
    from conftest import start_daemon

    tokens = tmp_path / "tokens"
    tokens.write_text("route-token-1\n")
    auth = {"Authorization": "Bearer route-token-1"}
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--token-file", str(tokens))
    try:
        for row in ROUTES:
            url = d.url(example_path(row["pattern"]))
            r = requests.request("PUT", url, headers=auth, timeout=10)
            assert r.status_code == 405, (row["pattern"], r.status_code, r.text)
            assert r.headers["Allow"] == row["methods"] + ", OPTIONS"
            assert r.json()["error"]["code"] == "method_not_allowed"
            method = row["methods"].split(",")[0]
            r = requests.request(method, url, timeout=10)
            assert r.status_code == (401 if row["auth"] == "TOKEN" else 200), (row["pattern"], r.status_code)
        names = deref(OPENAPI["paths"]["/v1/schemas/{name}"]["get"]["parameters"][0])["schema"]["enum"]
        for name in names:
            assert requests.get(d.url(f"/v1/schemas/{name}"), headers=auth, timeout=10).status_code == 200, name
        for name in ("openapi", "nowhere", ""):
            assert requests.get(d.url(f"/v1/schemas/{name}"), headers=auth, timeout=10).status_code == 404, name
        assert requests.get(d.url("/v1/openapi.json"), headers=auth, timeout=10).json()["paths"].keys() == OPENAPI["paths"].keys()
        text = requests.get(d.url("/metrics"), headers=auth, timeout=10).text
    finally:
        d.stop()
    labels = set(re.findall(r'^ntscontactd_requests_total\{route="([^"]*)"', text, re.M))
    assert labels == {r["label"] for r in ROUTES} | {"other"}  # "other": the 404s of the unknown names
    for row in ROUTES:
        assert re.search(rf'^ntscontactd_requests_total\{{route="{re.escape(row["label"])}",status="405"\}}', text,
                         re.M), row["pattern"]
