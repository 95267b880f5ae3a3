"""Compare the dumps of two releases (nts_cross dump DIR): per case, the
largest force difference relative to the largest force, and whether the
active contacts are the same (slave body and node, master body) and reach the
master through the same feature (segment, corner, vertex).

    .venv/bin/python bench/cross_dump.py BEFORE_DIR AFTER_DIR [--csv FILE]

Exit status 0 when every case has the same contacts and forces within 1e-13
of the largest force (issue 13's contract across releases), 1 otherwise."""
from __future__ import annotations

import argparse
import csv
import os
import struct
import sys

import numpy as np

RECORD = np.dtype([("key", "<i4", 4), ("gap", "<f8")])
TOLERANCE = 1e-13


def read(path: str) -> tuple[np.ndarray, np.ndarray]:
    data = open(path, "rb").read()
    (n,) = struct.unpack_from("<i", data, 0)
    forces = np.frombuffer(data, dtype="<f8", count=2 * n, offset=4).reshape(n, 2)
    (m,) = struct.unpack_from("<i", data, 4 + 16 * n)
    contacts = np.frombuffer(data, dtype=RECORD, count=m, offset=8 + 16 * n)
    return forces, contacts


def compare(before: str, after: str) -> list[dict]:
    rows = []
    for name in sorted(os.listdir(before)):
        if not name.endswith(".bin"):
            continue
        fa, ca = read(os.path.join(before, name))
        fb, cb = read(os.path.join(after, name))
        scale = float(np.abs(fa).max()) if fa.size else 0.0
        diff = float(np.abs(fa - fb).max()) / scale if scale > 0 else float(np.abs(fb).max())
        pairs_a = {tuple(k[:3]) for k in ca["key"]}
        pairs_b = {tuple(k[:3]) for k in cb["key"]}
        kinds_a = {tuple(k) for k in ca["key"]}
        kinds_b = {tuple(k) for k in cb["key"]}
        rows.append({
            "case": name[:-4],
            "contacts_before": len(ca),
            "contacts_after": len(cb),
            "same_contacts": pairs_a == pairs_b,
            "same_features": kinds_a == kinds_b,
            "force_diff": diff,
        })
    return rows


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--csv")
    args = ap.parse_args(argv)
    rows = compare(args.before, args.after)
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    bad = [r for r in rows if not r["same_contacts"] or r["force_diff"] > TOLERANCE]
    worst = max(rows, key=lambda r: r["force_diff"])
    print("%d cases, %d with other contacts, %d with other features; largest force difference %.3g of the "
          "largest force (%s)" % (len(rows), sum(not r["same_contacts"] for r in rows),
                                  sum(not r["same_features"] for r in rows), worst["force_diff"], worst["case"]))
    for r in bad:
        print("  differs: %(case)s contacts %(contacts_before)d -> %(contacts_after)d, force %(force_diff).3g" % r)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
