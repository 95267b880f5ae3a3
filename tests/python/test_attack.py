"""Slow clients from several addresses, each reopening every connection the
daemon cuts (issue 23, item 3; tests/load/attack.py): slow request headers,
slow TLS handshakes, slow bodies, from 5 addresses x 64 connections against
the default limits (--max-connections 256, --max-per-client 64). 0.2
answered 0 of 80, 6 of 59 and 1 of 80 honest probes in 40 s. Now a new
connection cuts the slowest connection of the address holding the most, so
the honest client (one connection, its own address) is served every time.
No timing is asserted: each probe waits up to 30 s, and must be answered."""
import pathlib
import sys

import pytest
import requests

from conftest import start_daemon

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests" / "load"))
import attack  # noqa: E402

PROBES = 12


@pytest.mark.parametrize("mode", attack.MODES)
def test_honest_probes_are_answered_under_a_slow_client_attack(paths, tmp_path, tls_pair, mode):
    flags = ["--quiet", "--threads", "2"]
    ca = None
    if mode == "tls":
        cert, key = tls_pair
        flags += ["--tls-cert", str(cert), "--tls-key", str(key)]
        ca = str(cert)
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", *flags)
    try:
        out = attack.run(d.port, mode, addresses=5, per_address=64, seconds=None, probes=PROBES,
                         probe_every=0.25, ca=ca)
        print(out)
        assert out["probes"] == PROBES
        assert out["answered"] == PROBES, out
        # The room was full: the attackers' connections were cut to make it.
        assert out["attack_connections"] > 5 * 64
        base = d.base.replace("http://", "https://") if ca else d.base
        h = requests.get(base + "/v1/health", verify=ca or True, timeout=30).json()
        assert h["shed"] > 0 and h["connections_open"] <= 256, h
    finally:
        assert d.stop() == 0
