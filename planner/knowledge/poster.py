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
        self._queue: queue.Queue[list[PointIn] | None] = queue.Queue()
        self.posted = 0
        self.failed = 0
        self.post_s = 0.0
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._drain, name="cpkb-poster", daemon=True)
            self._thread.start()

    def submit(self, points: list[PointIn]) -> None:
        if not points:
            return
        if self._background:
            self._queue.put(points)
        else:
            self._send(points)

    def close(self) -> None:
        """Wait until every submitted batch is posted (or has failed for good)."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None

    def _drain(self) -> None:
        while True:
            batch = self._queue.get()
            if batch is None:
                return
            # Merge whatever else is waiting into one request: fewer round trips under load.
            while True:
                try:
                    more = self._queue.get_nowait()
                except queue.Empty:
                    break
                if more is None:
                    self._send(batch)
                    return
                batch.extend(more)
            self._send(batch)

    def _send(self, points: list[PointIn]) -> None:
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
