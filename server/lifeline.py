"""A child process that leaves when its parent is gone: the one watchdog of the service's fit
worker and the bench's run workers.

A parent killed with SIGKILL cannot stop its children, and a child that holds both ends of its
pipes never sees EOF. So the child polls its parent id and exits once it changes. The parent
passes its own pid in: a child that read `os.getppid()` itself, after slow imports, could read
the pid of the process that adopted it (the parent already dead) and wait forever.
"""

from __future__ import annotations

import os
import threading
import time

POLL_S = 0.5


def exit_with_parent(parent_pid: int) -> None:
    """End this process now if `parent_pid` is no longer its parent, else as soon as that
    happens (a daemon thread polls)."""
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(
        target=_watch, args=(parent_pid,), name="cpkb-exit-with-parent", daemon=True
    ).start()


def _watch(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(POLL_S)
    os._exit(1)
