"""The history's writer: a process of its own that takes a run's records from the recorder (JSON lines on its
standard input) and writes them to the store, so the run never waits for SQLAlchemy's import, the database or a
store that does not answer (on a second core it costs the run next to nothing; ``benchmarks/run.py``).

Its standard output answers the recorder: ``{"warn": …}`` once when the store fails (the rest of the run then goes
to the local spool), ``{"history": …}`` for the HTML report.  When the recorder's process dies (SIGKILL) its input
ends: everything sent before is written, and the run stays marked not finished.
"""

from __future__ import annotations

import datetime as dt
import json
import sys
from collections.abc import Callable
from typing import Any

from hil.core.measurement import Measurement
from hil.core.redact import hide_password
from hil.history import config
from hil.history.store import RunInfo, Store, TestResult, one_line


class Writer:
    def __init__(self, say: Callable[[dict[str, Any]], None]) -> None:
        self.say = say
        self.store: Store | None = None
        self.url = ""
        self.run_id: int | None = None
        self.info: RunInfo | None = None
        self.unsent: list[TestResult] = []  # not yet in the store (normally just the test that finished)
        self.spooled = False
        self.warned = False
        self.dead = False  # the store and the spool both failed: nothing more is recorded

    # -- the operations ---------------------------------------------------------------------------------------------
    def start(self, url: str, info: dict[str, Any]) -> None:
        info = dict(info, started_at=dt.datetime.fromisoformat(info["started_at"]),
                    properties=[tuple(p) for p in info["properties"]])
        self.info, self.url = RunInfo(**info), url
        self._try(self._open_and_start)

    def test(self, result: dict[str, Any]) -> None:
        result = dict(result, measurements=[Measurement(**m) for m in result["measurements"]])
        self.unsent.append(TestResult(**result))
        self._try(self._flush)

    def history(self, bench: str, n: int) -> dict[str, Any]:
        found: dict[str, Any] = {"last": None, "values": []}

        def read() -> None:
            assert self.store is not None  # (_try refuses an action before the store is opened)
            last, values = self.store.bench_history(bench, self.run_id or 0, n)
            found.update(last=last, values=values)
        self._try(read)
        return {"history": found, "store": hide_password(self.url), "spooled": self.spooled}

    def finish(self, **values: Any) -> None:
        def write() -> None:
            store, run_id = self._started()
            store.finish_run(run_id, **values)
        self._try(write)

    def close(self) -> None:
        if self.store is not None:
            self.store.close()

    # -- failing over to the spool ------------------------------------------------------------------------------------
    def _open_and_start(self) -> None:
        if self.info is None:
            raise RuntimeError("a run's records came before its start")
        self.store = Store(self.url)
        self.run_id = self.store.start_run(self.info)

    def _started(self) -> tuple[Store, int]:
        """The store and this run's row in it (both set by :meth:`_open_and_start`, which :meth:`_try` runs
        before anything else reaches the store)."""
        if self.store is None or self.run_id is None:
            raise RuntimeError("the store was never opened")
        return self.store, self.run_id

    def _flush(self) -> None:
        store, run_id = self._started()
        with store.engine.begin() as conn:
            for result in self.unsent:
                store.add_test(run_id, result, conn)
        self.unsent.clear()

    def _try(self, action: Callable[[], None]) -> None:
        """Run a store action; on the first error say so once and carry on in the spool."""
        if self.dead or self.info is None:
            return
        try:
            if self.store is None and action != self._open_and_start:
                raise RuntimeError("the store was never opened")
            action()
        except Exception as exc:  # noqa: BLE001 - recording never fails a run
            self._fail_over(exc, action)

    def _fail_over(self, exc: Exception, action: Callable[[], None]) -> None:
        failed, spool = hide_password(self.url), config.spool_url()
        if self.spooled or self.url == spool:
            self._warn(f"history store {failed} failed ({one_line(exc)}): the rest of this run is not recorded")
            self.dead = True
            return
        try:
            if self.store is not None:
                self.store.close()
            self.store, self.spooled, self.url = None, True, spool
            self._open_and_start()
            if action != self._open_and_start:
                action()  # a test's write sends every test the store did not take
        except Exception as again:  # noqa: BLE001
            self._warn(f"history store {failed} unreachable ({one_line(exc)}), and the local spool too "
                       f"({one_line(again)}): this run is not recorded")
            self.dead = True
            return
        self._warn(f"history store {failed} unreachable ({one_line(exc)}): this run is kept in "
                   f"{hide_password(spool)} — `hil history sync` uploads it")

    def _warn(self, text: str) -> None:
        if not self.warned:
            self.warned = True
            self.say({"warn": text})


def _plain(value: Any) -> Any:
    return value.isoformat() if isinstance(value, (dt.datetime, dt.date)) else str(value)


def main() -> int:
    def say(message: dict[str, Any]) -> None:
        sys.stdout.write(json.dumps(message, default=_plain) + "\n")
        sys.stdout.flush()
    writer = Writer(say)
    try:
        for line in sys.stdin:  # ends when the recorder closes it, or its process dies
            message = json.loads(line)
            op = message.pop("op")
            if op == "start":
                writer.start(message["url"], message["info"])
            elif op == "test":
                writer.test(message["result"])
            elif op == "history":
                say(writer.history(message["bench"], message["n"]))
            elif op == "finish":
                writer.finish(**message)
    except BrokenPipeError:
        pass  # the recorder is gone; what it sent is written
    finally:
        writer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
