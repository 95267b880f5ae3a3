"""Bad input and the edges of the tools (issue 22, section 6).

- the CLI on a directory is bad input (exit 2, one line), not an internal error;
- every option of both programs takes `--x v` and `--x=v`, the byte limit is
  `--max-bytes` in both (the daemon's old `--max-body` still works, with a
  deprecation line), usage errors are clear and exit 2;
- `ntscontactd --help` names every route of the OpenAPI document;
- `python -m ntscontact convert`: a missing or unreadable file, a 3D mesh and a
  pinched mesh are each one clear line and a non-zero exit, never a traceback;
  the converter's triangle rule is the core's (checked on random meshes);
  `--penalty` is required."""
import json
import re
import shutil
import socket
import subprocess
import sys

import numpy as np
import pytest
import requests

from conftest import BUILD, REPO, start_daemon

CLI = BUILD / "bin" / "ntscontact"
DAEMON = BUILD / "bin" / "ntscontactd"
TWO_DISKS = REPO / "examples" / "two_disks.json"


def run_cli(*args, stdin=None, cwd=None, timeout=60):
    return subprocess.run([str(CLI), *map(str, args)], input=stdin, capture_output=True, cwd=cwd, timeout=timeout)


def help_options(binary):
    """The long options `binary --help` lists: {name: takes_a_value}."""
    text = subprocess.run([str(binary), "--help"], capture_output=True, text=True, timeout=30).stdout
    opts = {}
    for line in text.splitlines():
        if not line.startswith("  -"):
            continue
        for name, meta in re.findall(r"(?:^ {2}|, )(--[a-z][a-z-]*)(?:[ =]([A-Z][A-Za-z.|]*))?", line):
            opts[name] = bool(meta)
    return opts


def without_elapsed(text):
    doc = json.loads(text)
    doc["summary"].pop("elapsed_ms", None)
    return doc


# --------------------------------------------------------------- a directory

def test_a_directory_is_bad_input_not_an_internal_error(tmp_path):
    proc = run_cli(tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == b""
    err = proc.stderr.decode()
    assert err.count("\n") == 1 and err.startswith("ntscontact: ") and str(tmp_path) in err
    assert "directory" in err
    # the same for the frames
    proc = run_cli("--frames", tmp_path, TWO_DISKS)
    assert proc.returncode == 2 and proc.stdout == b""
    assert str(tmp_path) in proc.stderr.decode() and "directory" in proc.stderr.decode()


# --------------------------------------------------------------- CLI options

CLI_VALUES = {  # a valid value of every option with one, and what to compare
    "--alpha": "0.1", "--penalty": "50", "--search-radius": "0.2", "--solver": "newton",
    "--outputs": "forces,stiffness", "--output": "OUT", "--frames": "FRAMES", "--vtk": "VTK",
    "--max-bytes": "1M", "--max-depth": "40", "--max-bodies": "10", "--max-nodes": "1k",
    "--max-nodes-per-body": "1k", "--max-seconds": "30", "--max-candidates": "1M",
}
CLI_FLAGS = {"--validate", "--pretty", "--help", "--version"}


def test_cli_help_lists_the_options_this_test_knows():
    assert help_options(CLI) == {**{k: True for k in CLI_VALUES}, **{k: False for k in CLI_FLAGS}}


@pytest.mark.parametrize("name", sorted(CLI_VALUES))
def test_every_cli_option_takes_both_forms(name, tmp_path):
    scene = json.loads(TWO_DISKS.read_text())
    frames = tmp_path / "frames.bin"
    pos = np.concatenate([np.asarray(b["nodes"], dtype="<f8") for b in scene["bodies"]])
    frames.write_bytes(pos.tobytes() + (pos * 1.001).tobytes())
    got = []
    for form in ("space", "equals"):
        out = tmp_path / form
        out.mkdir()
        value = {"OUT": str(out / "out.json"), "FRAMES": str(frames), "VTK": str(out / "r.vtu")}.get(
            CLI_VALUES[name], CLI_VALUES[name])
        args = [name, value] if form == "space" else [f"{name}={value}"]
        proc = run_cli(*args, TWO_DISKS)
        assert proc.returncode == 0, (args, proc.stderr)
        assert proc.stderr == b""
        if name == "--output":
            assert proc.stdout == b""
            got.append(without_elapsed((out / "out.json").read_text()))
        elif name == "--frames":
            lines = proc.stdout.decode().splitlines()
            assert len(lines) == 2
            got.append([without_elapsed(line) for line in lines])
        else:
            got.append(without_elapsed(proc.stdout))
        if name == "--vtk":
            got.append((out / "r.vtu").read_bytes())
    assert got[0] == got[len(got) // 2]
    if name == "--vtk":
        assert got[1] == got[3] and got[1].startswith(b"<?xml")


@pytest.mark.parametrize("name, value, code", [
    ("--max-bytes", "100", "payload_too_large"),
    ("--max-depth", "2", "too_deep"),
    ("--max-bodies", "1", "limit_exceeded"),
    ("--max-nodes", "10", "limit_exceeded"),
    ("--max-nodes-per-body", "10", "limit_exceeded"),
])
def test_a_limit_given_with_equals_is_applied(name, value, code):
    for args in ([name, value], [f"{name}={value}"]):
        proc = run_cli(*args, TWO_DISKS)
        assert proc.returncode == 3, (args, proc.stderr)
        assert proc.stderr.decode().startswith(f"ntscontact: {code} at "), proc.stderr


def test_an_override_given_with_equals_is_applied():
    base = without_elapsed(run_cli("--outputs", "energy", TWO_DISKS).stdout)
    doubled = without_elapsed(run_cli("--outputs=energy", "--penalty=2000", TWO_DISKS).stdout)
    assert doubled["summary"]["energy"] == 2 * base["summary"]["energy"] > 0


@pytest.mark.parametrize("args, says", [
    (["--pretty=yes", "SCENE"], "option '--pretty' takes no value"),
    (["--validate=1", "SCENE"], "option '--validate' takes no value"),
    (["SCENE", "--alpha"], "option '--alpha' needs a value"),
    (["--alpha=", "SCENE"], "--alpha needs a number, not ''"),
    (["--max-body", "1M", "SCENE"], "unknown option '--max-body'"),
    (["--pen", "5", "SCENE"], "unknown option '--pen'"),
    (["--bogus=1", "SCENE"], "unknown option '--bogus=1'"),
    (["-x", "SCENE"], "unknown option '-x'"),
], ids=lambda a: " ".join(a) if isinstance(a, list) else "")
def test_cli_usage_errors_are_clear(args, says):
    proc = run_cli(*[TWO_DISKS if a == "SCENE" else a for a in args])
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == b""
    lines = proc.stderr.decode().splitlines()
    assert lines == [f"ntscontact: {says}", "Try 'ntscontact --help' for more information."]


def test_cli_options_after_the_scene_and_after_double_dash(tmp_path):
    a = without_elapsed(run_cli(TWO_DISKS, "--penalty=10").stdout)
    assert a == without_elapsed(run_cli("--penalty", "10", TWO_DISKS).stdout)
    assert a != without_elapsed(run_cli(TWO_DISKS).stdout)
    weird = tmp_path / "-scene.json"
    shutil.copy(TWO_DISKS, weird)
    proc = run_cli("--penalty", "10", "--", weird, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert without_elapsed(proc.stdout) == a
