"""Ctrl-C during a flight: a flag the flight loops poll, so that the report is written."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any


@contextlib.contextmanager
def ctrl_c_flag() -> Iterator[threading.Event]:
    """While inside: the first Ctrl-C (SIGINT) sets the yielded event, the next raises
    KeyboardInterrupt. A flag rather than an exception at an arbitrary point of the tick, where
    a callback could swallow it. Outside the main thread (no signal handlers) Ctrl-C keeps its
    default KeyboardInterrupt, which the caller handles as a second one."""
    interrupted = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield interrupted
        return

    def on_sigint(signum: int, frame: Any) -> None:
        if interrupted.is_set():
            raise KeyboardInterrupt
        interrupted.set()

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield interrupted
    finally:
        signal.signal(signal.SIGINT, previous)
