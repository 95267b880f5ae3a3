"""Reliability of the daemon under load and faults (issue 7), a short version
of bench/soak/soak.py: 16 keep-alive clients post valid and invalid scenes for
12 s while fault clients disconnect mid-upload, send garbage, trickle a body,
announce huge bodies, send oversized headers or nothing; then SIGTERM with the
load still running and requests held in flight. Every answer is compared with
the CLI's for the same bytes. Asserted: zero wrong answers, zero 5xx (a 503
"shutting down" after SIGTERM excepted), no load request lost before SIGTERM,
every held request answered right, the slow client cut off, the daemon exits 0.
"""
import importlib.util
import pathlib

import pytest

SOAK = pathlib.Path(__file__).resolve().parents[2] / "bench" / "soak" / "soak.py"


def _soak():
    spec = importlib.util.spec_from_file_location("nts_soak", SOAK)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def soak_result(paths, tmp_path_factory):
    for b in (paths.cli, paths.bin / "ntscontactd"):
        if not b.exists():
            pytest.fail(f"{b} is not built (NTS_BUILD_DIR={paths.build})")
    soak = _soak()
    log = tmp_path_factory.mktemp("soak") / "daemon.log"
    result = soak.run(paths.build, duration=12.0, connections=16, faults=True, sigterm=True, seed=11,
                      daemon_flags=("--quiet", "--timeout", "2"), log=lambda *a: None, log_path=log,
                      variants=2, held=4)
    result["_failures"] = soak.failures(result)
    result["_log"] = log
    return result


def test_no_wrong_answer_no_5xx(soak_result):
    r = soak_result
    assert r["requests"] > 0
    assert r["wrong_answers"] == 0, r["wrong_examples"]
    assert r["server_errors_5xx"] == 0, r["by_status"]
    assert r["transport_errors_before_sigterm"] == 0, r["transport_errors_examples"]
    assert set(r["by_status"]) <= {"200", "400", "413"}, r["by_status"]
    assert "200" in r["by_status"] and "400" in r["by_status"]


def test_faults_get_their_4xx_and_hurt_nobody(soak_result):
    r = soak_result
    assert r["fault_problems"] == []
    f = r["faults"]
    for kind, status in (("method", "405"), ("path", "404"), ("media_type", "415"), ("huge_length", "413")):
        if kind in f:
            assert set(f[kind]) <= {status}, (kind, f[kind])
    assert f["disconnect_mid_upload"].get("sent", 0) > 0
    assert all(not k.startswith("5") for k in f["garbage"]), f["garbage"]
    assert r["health_before_stop"]["status"] == 200


def test_slow_upload_is_cut_off(soak_result):
    slow = soak_result["faults"]["slow_upload"]
    # A 3 kB body at 20 bytes/s needs minutes; the daemon's upload budget is 2 s.
    assert slow.get("cut_off", 0) >= 1, slow
    assert slow.get("finished", 0) == 0, slow


def test_sigterm_mid_load(soak_result):
    r = soak_result
    assert r["held_in_flight_at_sigterm"] == 4
    assert r["held_results"] == [None] * 4, r["held_results"]
    assert r["daemon_exit"] == 0, pathlib.Path(r["_log"]).read_text(errors="replace")[-3000:]


def test_soak_verdict(soak_result):
    assert soak_result["_failures"] == []
