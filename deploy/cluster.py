"""A local cluster: N ntscontactd behind nginx, configured by deploy/nginx.conf.

    python3 deploy/cluster.py --daemons 3 [--port 8080] [-- DAEMON FLAGS...]

starts the daemons on free ports and nginx on --port, prints the address and
runs until Ctrl-C. The scale-out test and benchmark use the Cluster class.
nginx runs as the calling user from a prefix directory of its own (logs/,
tmp/ and the rendered configuration), so no root and no system nginx."""
from __future__ import annotations

import argparse
import os
import pathlib
import selectors
import shutil
import signal
import socket
import subprocess
import sys
import time
from typing import List, Optional, Sequence

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def find_nginx() -> Optional[str]:
    return shutil.which("nginx") or next((p for p in ("/usr/sbin/nginx",) if os.access(p, os.X_OK)), None)


def write_config(workdir: pathlib.Path, nginx_port: int, daemon_ports: Sequence[int]) -> pathlib.Path:
    """deploy/nginx.conf in `workdir`, with its upstreams.conf and listen.conf
    naming these ports; the path of the configuration."""
    conf = workdir / "nginx.conf"
    shutil.copyfile(HERE / "nginx.conf", conf)
    (workdir / "upstreams.conf").write_text(
        "".join(f"server 127.0.0.1:{p} max_fails=3 fail_timeout=2s;\n" for p in daemon_ports))
    (workdir / "listen.conf").write_text(f"listen 127.0.0.1:{nginx_port};\n")
    return conf


class Cluster:
    def __init__(self, daemon_bin: pathlib.Path, workdir: pathlib.Path, daemons: int = 3,
                 daemon_args: Sequence[str] = (), nginx: Optional[str] = None, port: int = 0) -> None:
        self.daemon_bin = pathlib.Path(daemon_bin)
        self.workdir = pathlib.Path(workdir)
        self.count = daemons
        self.daemon_args = list(daemon_args)
        self.nginx = nginx or find_nginx()
        if self.nginx is None:
            raise RuntimeError("nginx is not installed (scripts/install-deps.sh installs it)")
        self.port = port  # 0: a free one, chosen once the daemons have theirs (start)
        self.daemon_ports: List[int] = []
        self.daemons: List[Optional[subprocess.Popen]] = []
        self.proxy: Optional[subprocess.Popen] = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def daemon_url(self, i: int) -> str:
        return f"http://127.0.0.1:{self.daemon_ports[i]}"

    def _start_daemon(self, i: int, port: int) -> subprocess.Popen:
        log = open(self.workdir / f"daemon{i}.log", "ab")
        proc = subprocess.Popen([str(self.daemon_bin), "--port", str(port), "--session-id-header", "NTS-Session-Id",
                                 "--trusted-proxy", "127.0.0.1", "--max-connections", "1024", *self.daemon_args], stdout=subprocess.PIPE, stderr=log, stdin=subprocess.DEVNULL)
        log.close()
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        line = proc.stdout.readline().decode() if sel.select(20) else ""
        sel.close()
        if not line.startswith("ntscontactd listening on "):
            proc.kill()
            proc.wait()
            raise RuntimeError(f"ntscontactd {i} did not start: {line!r}")
        if i < len(self.daemon_ports):
            self.daemon_ports[i] = int(line.rsplit(":", 1)[1])
        else:
            self.daemon_ports.append(int(line.rsplit(":", 1)[1]))
        return proc

    def start(self) -> "Cluster":
        self.workdir.mkdir(parents=True, exist_ok=True)
        for d in ("logs", "tmp"):
            (self.workdir / d).mkdir(exist_ok=True)
        for i in range(self.count):
            self.daemons.append(self._start_daemon(i, 0))
        # After the daemons: a port chosen before them could be given to one
        # of them (both come from the kernel's free ports), and the cluster
        # would then talk to that daemon directly, not through nginx.
        if self.port == 0:
            self.port = free_port()
        pid = self.workdir / "logs" / "nginx.pid"
        pid.unlink(missing_ok=True)
        conf = write_config(self.workdir, self.port, self.daemon_ports)
        self.proxy = subprocess.Popen([self.nginx, "-p", str(self.workdir), "-c", str(conf), "-g", "daemon off;"],
                                      stdout=subprocess.DEVNULL, stderr=open(self.workdir / "nginx.stderr", "wb"))
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            if self.proxy.poll() is not None:
                raise RuntimeError("nginx exited: " + (self.workdir / "nginx.stderr").read_text())
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                if pid.exists():  # written once nginx has bound its port (and not before)
                    return self
                time.sleep(0.05)
            except OSError:
                time.sleep(0.05)
        raise RuntimeError("nginx did not listen")

    def kill(self, i: int) -> None:
        """SIGKILL daemon i: its sessions are gone, as in a crash."""
        proc = self.daemons[i]
        if proc is not None:
            proc.kill()
            proc.wait()
            self.daemons[i] = None

    def restart(self, i: int) -> None:
        """Daemon i again, on the port nginx knows (a fresh process: no sessions)."""
        deadline = time.monotonic() + 10
        while True:
            try:
                self.daemons[i] = self._start_daemon(i, self.daemon_ports[i])
                return
            except RuntimeError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)

    def stop(self) -> List[int]:
        """Stop nginx and the daemons; the daemons' exit statuses."""
        if self.proxy is not None:
            self.proxy.send_signal(signal.SIGQUIT)
            try:
                self.proxy.wait(10)
            except subprocess.TimeoutExpired:
                self.proxy.kill()
                self.proxy.wait()
        codes = []
        for proc in self.daemons:
            if proc is None:
                continue
            proc.send_signal(signal.SIGTERM)
            try:
                codes.append(proc.wait(40))
            except subprocess.TimeoutExpired:
                proc.kill()
                codes.append(proc.wait())
        self.daemons = []
        return codes

    def __enter__(self) -> "Cluster":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--daemons", type=int, default=3)
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--bin", default=str(REPO / os.environ.get("NTS_BUILD_DIR", "build") / "bin" / "ntscontactd"))
    ap.add_argument("--workdir", default=str(REPO / "build" / "cluster"))
    ap.add_argument("daemon_args", nargs="*", help="flags for every daemon (after --)")
    args = ap.parse_args(argv)
    with Cluster(pathlib.Path(args.bin), pathlib.Path(args.workdir), args.daemons, args.daemon_args,
                 port=args.port) as c:
        print(f"ntscontact cluster: {c.url} -> {', '.join(map(str, c.daemon_ports))} (Ctrl-C stops)", flush=True)
        try:
            signal.pause()
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
