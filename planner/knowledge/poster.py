"""Posting points off the search's critical path: batches per rollout, one background thread.

The thread may linger after a batch arrives for more to join it (`linger_s`): each request costs
the planner's process CPU time while the thread holds the GIL, and a fast search hands over a
batch every few milliseconds. Whoever waits for a batch to be stored cuts the lingering short.

Each point carries an idempotency key (run, rollout, index), so the client's retries never store
a point twice. A failed post is counted, never raised into the search: the binding search goes on
without the knowledge base rather than crash.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Sequence

from contract.models import PointIn

log = logging.getLogger(__name__)

PostFn = Callable[[Sequence[PointIn]], object]


class _Flush:
    """Put by `wait_for`: send what is queued now, without lingering."""


_FLUSH = _Flush()


class PointPoster:
    def __init__(self, post: PostFn, *, background: bool = True, linger_s: float = 0.0) -> None:
        self._post = post
        self._background = background
        self._linger_s = linger_s
        self._queue: queue.Queue[tuple[int, list[PointIn]] | _Flush | None] = queue.Queue()
        self.submitted = 0  # batches handed over so far; a batch's number is its rank
        self.done = 0  # batches sent (or given up), in order
        self.posted = 0
        self.failed = 0
        self.post_s = 0.0
        self._sent = threading.Condition()
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._drain, name="cpkb-poster", daemon=True)
            self._thread.start()

    def submit(self, points: list[PointIn]) -> int:
        """Hand over one batch; returns its number (`done >= number` once it is sent)."""
        if not points:
            return self.submitted
        self.submitted += 1
        if self._background:
            self._queue.put((self.submitted, points))
        else:
            self._send(self.submitted, points)
        return self.submitted

    def wait_for(self, number: int) -> None:
        """Block until batch `number` has been sent (or given up)."""
        if self._thread is not None and self.done < number:
            self._queue.put(_FLUSH)
        with self._sent:
            self._sent.wait_for(lambda: self.done >= number or self._thread is None)

    def close(self) -> None:
        """Wait until every submitted batch is posted (or has failed for good)."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None

    def _drain(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            if isinstance(item, _Flush):
                continue
            number, batch = item
            # Merge what else arrives within the linger (or is waiting) into one request.
            deadline = time.monotonic() + self._linger_s
            closing = False
            while True:
                wait = deadline - time.monotonic()
                try:
                    more = self._queue.get(timeout=wait) if wait > 0 else self._queue.get_nowait()
                except queue.Empty:
                    break
                if more is None:
                    closing = True
                    break
                if isinstance(more, _Flush):
                    deadline = time.monotonic()
                    continue
                number = more[0]
                batch.extend(more[1])
            self._send(number, batch)
            if closing:
                return

    def _send(self, number: int, points: list[PointIn]) -> None:
        started = time.perf_counter()
        try:
            for start in range(0, len(points), 500):
                self._post(points[start : start + 500])
            self.posted += len(points)
        except Exception as exc:  # the search must outlive a knowledge-base outage
            self.failed += len(points)
            log.warning("posting %d points failed: %s", len(points), exc)
        finally:
            self.post_s += time.perf_counter() - started
            with self._sent:
                self.done = number
                self._sent.notify_all()
