"""GET /metrics: the Prometheus text format, read back with the reference
parser (prometheus_client), and every counter checked against the requests
the test made."""
import requests
from prometheus_client.parser import text_string_to_metric_families

from conftest import settled_health, start_daemon


def _scrape(d, **kw):
    r = requests.get(d.url("/metrics"), timeout=10, **kw)
    assert r.status_code == 200, r.text
    assert r.headers["Content-Type"].startswith("text/plain; version=0.0.4")
    samples = {}
    for family in text_string_to_metric_families(r.text):
        for s in family.samples:
            samples[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return samples


def _get(samples, name, **labels):
    return samples.get((name, tuple(sorted(labels.items()))), 0.0)


def test_metrics_count_what_was_asked(paths, tmp_path):
    example = (paths.examples / "two_disks.json").read_bytes()
    json_h = {"Content-Type": "application/json"}
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        s0 = _scrape(d)
        assert _get(s0, "ntscontactd_evaluations_total") == 0
        summaries = []
        for _ in range(3):
            r = requests.post(d.url("/v1/contact"), data=example, headers=json_h, timeout=10)
            summaries.append(r.json()["summary"])
        assert requests.post(d.url("/v1/contact"), data=b"{", headers=json_h, timeout=10).status_code == 400
        assert requests.post(d.url("/v1/contact"), data=example, timeout=10,
                             headers={"Content-Type": "text/plain"}).status_code == 415
        assert requests.get(d.url("/nowhere"), timeout=10).status_code == 404
        created = requests.post(d.url("/v1/scenes"), data=example, headers=json_h, timeout=10)
        assert created.status_code == 201
        step = requests.post(d.url(created.headers["Location"] + "/contact"), timeout=10)
        summaries.append(step.json()["summary"])

        settled_health(d)
        s = _scrape(d)
        assert _get(s, "ntscontactd_requests_total", route="/v1/contact", status="200") == 3
        assert _get(s, "ntscontactd_requests_total", route="/v1/contact", status="400") == 1
        assert _get(s, "ntscontactd_requests_total", route="/v1/contact", status="415") == 1
        assert _get(s, "ntscontactd_requests_total", route="other", status="404") == 1
        assert _get(s, "ntscontactd_requests_total", route="/v1/scenes", status="201") == 1
        assert _get(s, "ntscontactd_requests_total", route="/v1/scenes/{id}/contact", status="200") == 1
        assert _get(s, "ntscontactd_requests_total", route="/metrics", status="200") == 1  # the first scrape
        assert _get(s, "ntscontactd_evaluations_total") == 4
        assert _get(s, "ntscontactd_surface_nodes_evaluated_total") == sum(x["surface_nodes"] for x in summaries)
        assert _get(s, "ntscontactd_contacts_total") == sum(x["contacts"] for x in summaries)
        assert _get(s, "ntscontactd_refusals_total", reason="unsupported_media_type") == 1
        assert _get(s, "ntscontactd_sessions") == 1
        assert _get(s, "ntscontactd_sessions_created_total") == 1
        assert _get(s, "ntscontactd_memory_in_use_bytes") == 0
        assert _get(s, "ntscontactd_memory_budget_bytes") > 0
        # The histogram: cumulative buckets, +Inf equal to the count, the sum positive.
        route = "/v1/contact"
        buckets = [(float(dict(k[1])["le"]), v) for k, v in s.items()
                   if k[0] == "ntscontactd_request_duration_seconds_bucket" and dict(k[1])["route"] == route]
        buckets.sort()
        values = [v for _, v in buckets]
        assert values == sorted(values) and buckets[-1][0] == float("inf")
        assert buckets[-1][1] == _get(s, "ntscontactd_request_duration_seconds_count", route=route) == 5
        assert _get(s, "ntscontactd_request_duration_seconds_sum", route=route) > 0
    finally:
        assert d.stop() == 0


def test_metrics_need_the_token(paths, tmp_path):
    tokens = tmp_path / "tokens"
    tokens.write_text("metrics-token\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--token-file", str(tokens))
    try:
        r = requests.get(d.url("/metrics"), timeout=10)
        assert r.status_code == 401
        auth = {"Authorization": "Bearer metrics-token"}
        settled_health(d, headers=auth)
        s = _scrape(d, headers=auth)
        assert _get(s, "ntscontactd_refusals_total", reason="unauthorized") == 1
    finally:
        assert d.stop() == 0
