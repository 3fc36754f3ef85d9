"""Ctrl-C that is not lost where it lands.

Python delivers a SIGINT as a KeyboardInterrupt wherever the main thread is. Inside a C library's
callback (llvmlite's, while numba compiles a hot loop on a machine's first run) that exception is
raised and dropped, and the program goes on. `Interrupts` remembers the signal, so the long work
under it (`ata run`/`ata eval`'s units and epochs, `ata train`'s steps) stops at its next
`check()`, at a point where what has ended is recorded.
"""

from __future__ import annotations

import signal
import threading


class Interrupts:
    """Within its `with` block, Ctrl-C raises KeyboardInterrupt as Python's own handler does and
    is remembered: `check()` raises it again where the first was lost. Only Python's default
    handler, in the main thread, is replaced (and put back on leaving)."""

    def __enter__(self) -> "Interrupts":
        self.hit, self.previous = False, None
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame) -> None:
        self.hit = True
        raise KeyboardInterrupt

    def check(self) -> None:
        """Raise KeyboardInterrupt if a Ctrl-C came since the block began."""
        if self.hit:
            raise KeyboardInterrupt

    def __exit__(self, *exc) -> None:
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
