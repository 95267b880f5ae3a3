"""The number printer's multipliers (codec/src/numfmt_pow5.h) are what
codec/tools/gen_pow5.py computes with exact integers: the committed header is
its output, byte for byte, and a few entries are checked against their
definition here too."""
import re
import subprocess
import sys

from conftest import REPO

HEADER = REPO / "codec" / "src" / "numfmt_pow5.h"
TOOL = REPO / "codec" / "tools" / "gen_pow5.py"


def test_header_is_the_generators_output():
    out = subprocess.run([sys.executable, str(TOOL)], capture_output=True, text=True, check=True).stdout
    assert out == HEADER.read_text()


def entries(name):
    text = HEADER.read_text()
    body = text[text.index(f"{name}["):]
    body = body[:body.index("};")]
    pairs = re.findall(r"\{UINT64_C\(0x([0-9a-f]{16})\), UINT64_C\(0x([0-9a-f]{16})\)\}", body)
    return [int(hi, 16) << 64 | int(lo, 16) for lo, hi in pairs]


def test_entries_by_their_definition():
    inv, pos = entries("ntsj_pow5_inv"), entries("pow5")
    assert len(inv) == 342 and len(pos) == 326
    for q in (0, 1, 2, 21, 22, 100, 341):  # 10^-q's multiplier: 2^(bits(5^q) - 1 + 125) / 5^q, rounded up
        p = 5 ** q
        assert inv[q] == (1 << (p.bit_length() - 1 + 125)) // p + 1
        assert inv[q] * p > 1 << (p.bit_length() - 1 + 125)
    for i in (0, 1, 2, 54, 55, 56, 200, 325):  # 5^i's leading 125 bits
        p = 5 ** i
        assert pos[i].bit_length() == 125
        s = p.bit_length() - 125
        assert pos[i] == (p >> s if s >= 0 else p << -s)
