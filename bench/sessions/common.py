"""What the session benchmarks share: a daemon of their own, and a section of
docs/benchmarks.md replaced in place."""
import csv
import os
import pathlib
import re
import subprocess

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))


def provenance():
    """Where a table comes from: the day, the commit (marked when the tree
    has changes) and the machine's processor and cores."""
    import datetime
    import platform

    def git(*args):
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True).stdout.strip()

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs", ":!bench/results"):  # (what runs)
        commit += " with changes"
    cpu = platform.processor() or "unknown processor"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"Measured {datetime.date.today().isoformat()}, commit {commit}, on {os.cpu_count()} cores of "
            f"{cpu} ({BUILD.name}'s binaries).")


def start_daemon(max_body="512M", binary=None):
    """ntscontactd (BUILD's, or `binary`) on a free loopback port, one
    evaluation thread: (process, port)."""
    proc = subprocess.Popen([str(binary or BUILD / "bin" / "ntscontactd"), "--port", "0", "--quiet", "--threads", "1",
                             "--max-bytes", max_body, "--session-memory", "8G"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    line = proc.stdout.readline().decode()
    if not line.startswith("ntscontactd listening on "):
        proc.kill()
        raise SystemExit(f"ntscontactd did not start: {line!r}")
    return proc, int(line.rsplit(":", 1)[1])


def request(conn, method, path, body=None, headers=None):
    """One request on an http.client connection: (response, body); a status
    of 300 or more ends the benchmark with it."""
    conn.request(method, path, body=body, headers=headers or {})
    r = conn.getresponse()
    data = r.read()
    if r.status >= 300:
        raise SystemExit(f"{method} {path}: {r.status} {data[:300]!r}")
    return r, data


def replace_section(path, title, section):
    """Put `section` (starting with `title`) in the markdown file at `path`, in
    place of the section of that title, or at the end. The old section ends
    at the next heading of its level or above, or at the first of its
    subsections that `section` does not write (another program's, such as
    "Many clients" under "Scale-out behind nginx"), which stays."""
    path = pathlib.Path(path)
    doc = path.read_text() if path.exists() else ""
    start = doc.find(title + "\n")
    if start < 0:
        doc = doc.rstrip("\n") + "\n\n" + section if doc.strip() else section
    else:
        level = len(title) - len(title.lstrip("#"))
        own = {line for line in section.splitlines() if line.startswith("#")}
        end, fenced, at = -1, False, start + len(title) + 1
        for line in doc[at:].splitlines(keepends=True):
            if line.startswith("```"):
                fenced = not fenced  # (a shell comment in a code block is no heading)
            m = None if fenced else re.match(r"(#+) ", line)
            if m and (len(m.group(1)) <= level or line.rstrip("\n") not in own):
                end = at - 1
                break
            at += len(line)
        # one blank line before the next section's title
        doc = doc[:start] + (section.rstrip("\n") + "\n\n" + doc[end + 1:] if end >= 0 else section)
    path.write_text(doc)


def write_results(rows, csv_name, out, title, section):
    """The rows to bench/results/CSV_NAME, the section into the markdown file
    `out`; when `out` is not docs/benchmarks.md (a run of one's own), the
    CSV goes beside it instead, and the committed results stay as they are."""
    docs = REPO / "docs" / "benchmarks.md"
    own = pathlib.Path(out).resolve() != docs.resolve()
    results = (pathlib.Path(out).resolve().parent if own else REPO / "bench" / "results") / csv_name
    with open(results, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    replace_section(out, title, section)
    print(f"wrote {results} and {out}")
