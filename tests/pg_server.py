"""A throw-away PostgreSQL cluster for the history tests: Debian's ``postgresql`` package (``.ci/run`` installs it
where it can), ``initdb`` into a temporary directory, ``pg_ctl`` on a free loopback port, trust authentication, no
fsync; stopped and removed at the end.  As root, the server runs as the package's ``postgres`` user (PostgreSQL
refuses to run as root).  ``NO_POSTGRES`` says why none can be started here (the tests then skip with it)."""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import uuid
from pathlib import Path


def _bin_dir() -> Path | None:
    found = shutil.which("pg_ctl")
    if found:
        return Path(found).resolve().parent
    versions = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"), key=lambda p: int(p.split("/")[4]))
    return Path(versions[-1]).parent if versions else None


def _why_not() -> str | None:
    if _bin_dir() is None:
        return "PostgreSQL is not installed (Debian's postgresql package: .ci/run installs it as root)"
    try:
        import psycopg  # noqa: F401
    except ImportError:
        return "psycopg is not installed (pip install 'hil[postgresql]')"
    if os.geteuid() == 0:
        try:
            pwd.getpwnam("postgres")
        except KeyError:
            return "running as root with no 'postgres' user to run the server as (PostgreSQL refuses root)"
    return None


NO_POSTGRES = _why_not()


def _free_port() -> int:
    with socket.socket() as s:  # PostgreSQL takes no port 0: ask the OS for a free one, then hand it over
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    def __init__(self) -> None:
        assert NO_POSTGRES is None, NO_POSTGRES
        self.bin = _bin_dir()
        self.dir = Path(tempfile.mkdtemp(prefix="hil-pg-"))
        self.data = self.dir / "data"
        self._user = pwd.getpwnam("postgres") if os.geteuid() == 0 else None
        if self._user is not None:
            os.chown(self.dir, self._user.pw_uid, self._user.pw_gid)
        self._run("initdb", "-D", str(self.data), "-U", "hil", "--auth=trust", "-N", "-E", "UTF8", "--locale=C")
        for _ in range(5):
            self.port = _free_port()
            try:
                self._ctl("start")
                break
            except subprocess.CalledProcessError:
                continue  # the port was taken between asking and starting: another
        else:
            raise RuntimeError(f"PostgreSQL did not start: {(self.dir / 'log').read_text(errors='replace')[-2000:]}")

    def _demote(self) -> None:
        if self._user is not None:
            os.setgid(self._user.pw_gid)
            os.setuid(self._user.pw_uid)

    def _run(self, tool: str, *args: str) -> None:
        subprocess.run([str(self.bin / tool), *args], check=True, capture_output=True, preexec_fn=self._demote,
                       cwd=self.dir, timeout=120)

    def _ctl(self, action: str) -> None:
        options = f"-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=40"
        self._run("pg_ctl", "-D", str(self.data), "-o", options, "-l", str(self.dir / "log"), "-w", "-t", "60",
                  action)

    def url(self, database: str = "postgres") -> str:
        return f"postgresql+psycopg://hil@127.0.0.1:{self.port}/{database}"

    def new_database(self) -> str:
        """A fresh, empty database's URL (each test its own)."""
        name = f"t_{uuid.uuid4().hex[:12]}"
        self.sql(f"CREATE DATABASE {name}")
        return self.url(name)

    def sql(self, statement: str) -> None:
        import psycopg
        with psycopg.connect(f"host=127.0.0.1 port={self.port} user=hil dbname=postgres", autocommit=True) as conn:
            conn.execute(statement)

    def refuse(self, database: str, refuse: bool = True) -> None:
        """Make ``database`` unreachable (connections refused, those open ended) or reachable again."""
        self.sql(f"ALTER DATABASE {database} WITH ALLOW_CONNECTIONS {'false' if refuse else 'true'}")
        if refuse:
            self.sql(f"SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = '{database}'")

    def stop(self) -> None:
        try:
            self._run("pg_ctl", "-D", str(self.data), "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(self.dir, ignore_errors=True)
