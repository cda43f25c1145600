"""Posting points off the search's critical path: batches per rollout, one background thread.

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

from client.models import PointIn

log = logging.getLogger(__name__)

PostFn = Callable[[Sequence[PointIn]], object]


class PointPoster:
    def __init__(self, post: PostFn, *, background: bool = True) -> None:
        self._post = post
        self._background = background
        self._queue: queue.Queue[tuple[int, list[PointIn]] | None] = queue.Queue()
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
            number, batch = item
            # Merge whatever else is waiting into one request: fewer round trips under load.
            while True:
                try:
                    more = self._queue.get_nowait()
                except queue.Empty:
                    break
                if more is None:
                    self._send(number, batch)
                    return
                number = more[0]
                batch.extend(more[1])
            self._send(number, batch)

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
