"""Running one piece of client work on several threads at once, for the servers' parallel-client tests."""

from __future__ import annotations

import threading
from collections.abc import Callable


def run_clients(work: Callable[[int], None], clients: int, join_timeout: float) -> None:
    """``work(n)`` for n in 0…clients−1, each on its own thread; raises the first failure of any (all of them in the
    message), or if a thread is still running after ``join_timeout`` seconds."""
    errors: list[BaseException] = []

    def run(n: int) -> None:
        try:
            work(n)
        except BaseException as exc:  # noqa: BLE001 - reported below, from the test's thread
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(n,), daemon=True) for n in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(join_timeout)
    hung = sum(t.is_alive() for t in threads)
    assert not hung, f"{hung} of {clients} clients still running after {join_timeout} s"
    if errors:
        raise AssertionError(f"{len(errors)} of {clients} clients failed: {errors}") from errors[0]
