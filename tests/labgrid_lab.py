"""A real labgrid lab on 127.0.0.1 for the tests: ``labgrid-coordinator`` and ``labgrid-exporter`` (ports chosen by
the OS), places made with ``labgrid-client`` as a lab admin would.

labgrid lives in its own environment (its ``pyserial-labgrid`` fork must not replace the test environment's pyserial):
``scripts/e2e_matrix.py`` makes ``.venv-labgrid`` with ``pip install -e '.[labgrid]'``; ``$HIL_LABGRID_BIN`` or a
``labgrid-coordinator`` on PATH work too.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from tests import processes
from tests.conftest import REPO

LABGRID = "labgrid==26.0.1"


def labgrid_bin() -> Path | None:
    """The directory holding labgrid-coordinator, -exporter and -client, or None."""
    on_path = shutil.which("labgrid-coordinator")
    for candidate in (os.environ.get("HIL_LABGRID_BIN"), REPO / ".venv-labgrid" / "bin",
                      Path(on_path).parent if on_path else None):
        if candidate and (Path(candidate) / "labgrid-coordinator").is_file():
            return Path(candidate)
    return None


def ser2net() -> str | None:
    """labgrid's exporter runs ser2net for a RawSerialPort (it looks on PATH, then in /usr/sbin)."""
    return shutil.which("ser2net") or next((p for p in ("/usr/sbin/ser2net",) if os.access(p, os.X_OK)), None)


MISSING = (None if labgrid_bin() else
           "labgrid is not installed: python3 -m venv .venv-labgrid && .venv-labgrid/bin/pip install -e '.[labgrid]' "
           "(as scripts/e2e_matrix.py does), or set HIL_LABGRID_BIN") or \
          (None if ser2net() else "ser2net is not installed (apt-get install ser2net, as .ci/run does)")


@dataclass
class RunningLab:
    bin: Path
    coordinator: str  # HOST:PORT
    log: Path  # the coordinator's output: "PLACE: place acquired by …", "PLACE: place released"

    def client(self, *args: str, place: str | None = None) -> str:
        cmd = [str(self.bin / "labgrid-client"), "-x", self.coordinator, *(["-p", place] if place else []), *args]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
        assert proc.returncode == 0, f"{' '.join(cmd)}: {proc.stderr or proc.stdout}"
        return proc.stdout

    @property
    def hil_python(self) -> Path | None:
        """The labgrid environment's Python when hil is installed there too (``hil[labgrid]``), else None."""
        return self.bin / "python" if (self.bin / "hil").is_file() else None

    def events(self, place: str) -> list[str]:
        """"acquired" / "released", in the coordinator's order, for ``place``."""
        return re.findall(rf"^{re.escape(place)}: place (acquired|released)", self.log.read_text(), re.M)


def wait_for(path: Path, pattern: str, timeout: float, proc: subprocess.Popen | None = None) -> re.Match:
    """The first match of ``pattern`` in the file a process writes (polled; fails naming what it said)."""
    deadline = time.monotonic() + timeout
    while True:
        text = path.read_text(errors="replace") if path.exists() else ""
        found = re.search(pattern, text, re.M)
        if found:
            return found
        if time.monotonic() > deadline or (proc is not None and proc.poll() is not None):
            raise AssertionError(f"{path.name}: no {pattern!r} within {timeout} s; it says:\n{text[-3000:]}")
        time.sleep(0.1)


@contextlib.contextmanager
def running_lab(directory: Path, exporter: str, places: dict[str, tuple[str, str]]) -> Iterator[RunningLab]:
    """A coordinator and one exporter (``exporter``: its YAML, published as exporter "lab-host"), and ``places``:
    name → (match pattern, "key=value …" tags).  Both are stopped (the exporter with the ser2net it started)."""
    bin_ = labgrid_bin()
    assert bin_ is not None, MISSING
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "exporter.yaml").write_text(exporter)
    log = directory / "coordinator.log"
    started: list[subprocess.Popen] = []
    try:
        with open(log, "w") as out:  # the coordinator keeps its places in its working directory
            started.append(processes.spawn([str(bin_ / "labgrid-coordinator"), "-l", "127.0.0.1:0"], cwd=directory,
                                            stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                            env={**os.environ, "PYTHONUNBUFFERED": "1"}))
        address = wait_for(log, r"^listening on (\S+:\d+)$", 30, started[0]).group(1)
        with open(directory / "exporter.log", "w") as out:  # its own session: ser2net children stop with it
            started.append(processes.spawn([str(bin_ / "labgrid-exporter"), "-c", address, "-n", "lab-host",
                                             "--hostname", "127.0.0.1", "exporter.yaml"], cwd=directory, stdout=out,
                                            stderr=subprocess.STDOUT, start_new_session=True,
                                            env={**os.environ, "PYTHONUNBUFFERED": "1"}))
        lab = RunningLab(bin_, address, log)
        groups = {pattern.split("/")[1] for pattern, _ in places.values()}
        deadline = time.monotonic() + 30
        while not all(f"lab-host/{g}/" in lab.client("resources") for g in groups):
            assert time.monotonic() < deadline and started[1].poll() is None, \
                (directory / "exporter.log").read_text()[-3000:]
            time.sleep(0.2)

        def create(name: str) -> None:
            pattern, tags = places[name]
            lab.client("create", place=name)
            lab.client("add-match", pattern, place=name)
            lab.client("set-tags", *tags.split(), place=name)
        with ThreadPoolExecutor(len(places)) as pool:
            list(pool.map(create, places))
        yield lab
    finally:
        for proc in reversed(started):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)  # what it started (ser2net) and left behind


@contextlib.contextmanager
def refused_port() -> Iterator[int]:
    """A loopback port that refuses connections for as long as this lasts: bound (so nobody else takes it), never
    listening — the wire of a PLC that is switched off."""
    import socket
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    try:
        yield sock.getsockname()[1]
    finally:
        sock.close()
