"""Read the X-macro tables of the C headers back (issue 24 §3), so that the
tests can compare them with the schemas and OpenAPI, written independently.

A row is `XX(a, b, "c", ...)`; its cells are split at the commas outside
quotes and parentheses, and a cell that is a C string literal (or several,
concatenated) becomes its text."""
import re
from pathlib import Path
from typing import Dict, List

REPO = Path(__file__).resolve().parents[2]


def _cells(text: str) -> List[str]:
    cells, depth, quote, cur = [], 0, False, ""
    i = 0
    while i < len(text):
        ch = text[i]
        if quote:
            cur += ch
            if ch == "\\":
                cur += text[i + 1]
                i += 1
            elif ch == '"':
                quote = False
        elif ch == '"':
            quote = True
            cur += ch
        elif ch == "(":
            depth += 1
            cur += ch
        elif ch == ")":
            depth -= 1
            cur += ch
        elif ch == "," and depth == 0:
            cells.append(cur.strip())
            cur = ""
        else:
            cur += ch
        i += 1
    cells.append(cur.strip())
    return [_literal(c) for c in cells]


def _literal(cell: str) -> str:
    parts = re.findall(r'"((?:[^"\\]|\\.)*)"', cell)
    if parts and re.fullmatch(r'(\s*"(?:[^"\\]|\\.)*"\s*)+', cell):
        return "".join(parts).encode().decode("unicode_escape")
    return cell


def macro_rows(header: str, macro: str) -> List[List[str]]:
    """The rows of `#define MACRO(XX) ...` in `header` (relative to the repository)."""
    text = (REPO / header).read_text()
    m = re.search(rf"#define {macro}\(XX\)((?:.*\\\n)*.*)", text)
    assert m, f"{macro} not in {header}"
    body = m.group(1).replace("\\\n", " ")
    rows, i = [], 0
    while True:
        j = body.find("XX(", i)
        if j < 0:
            return rows
        depth, k = 0, j + 2
        quote = False
        while True:
            ch = body[k]
            if quote:
                if ch == "\\":
                    k += 1
                elif ch == '"':
                    quote = False
            elif ch == '"':
                quote = True
            elif ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
                if depth == 0:
                    break
            k += 1
        rows.append(_cells(body[j + 3:k]))
        i = k + 1


OPTION_COLUMNS = ["id", "field", "json", "flag", "metavar", "kind", "ctype", "default", "min", "max", "bound",
                  "check", "presence", "doors", "names", "help"]


def options() -> List[Dict[str, str]]:
    return [dict(zip(OPTION_COLUMNS, row)) for row in
            macro_rows("core/include/ntscontact/tables.h", "NTS_OPTION_MAP")]


def enum_names(macro: str) -> Dict[str, str]:
    """{C enumerator: JSON name} of a NTS_*_NAMES table."""
    return {row[0]: row[1] for row in macro_rows("core/include/ntscontact/tables.h", macro)}


OUTPUT_COLUMNS = ["id", "bit", "name", "result", "records"]


def outputs() -> List[Dict[str, str]]:
    return [dict(zip(OUTPUT_COLUMNS, row)) for row in
            macro_rows("core/include/ntscontact/tables.h", "NTS_OUTPUT_MAP")]


ROUTE_COLUMNS = ["id", "pattern", "methods", "param", "body", "auth", "handler", "label", "evaluates"]


def routes() -> List[Dict[str, str]]:
    """The daemon's routes (server/src/routes.h), one dict a row; `methods`
    stays the Allow header's text ("GET, HEAD")."""
    return [dict(zip(ROUTE_COLUMNS, row)) for row in macro_rows("server/src/routes.h", "NTSD_ROUTE_MAP")]
