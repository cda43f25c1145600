"""The background poster: batches merged into one request while it lingers, and a wait for a
stored batch that does not wait out the linger."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence

from contract.models import PointIn
from planner.knowledge.poster import PointPoster

GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Inv-kin"},
        {
            "id": "d",
            "role": "decision",
            "label": "#dir",
            "domain": {"kind": "categorical", "choices": ["top", "front"]},
        },
    ],
    "edges": [{"source": "d", "target": "f", "label": "grasp"}],
}
LONG = 60.0  # a linger no test waits out


class Recorded:
    """A post function that keeps each request's point keys."""

    def __init__(self) -> None:
        self.requests: list[list[str]] = []
        self.lock = threading.Lock()

    def __call__(self, points: Sequence[PointIn]) -> None:
        with self.lock:
            self.requests.append([p.key or "" for p in points])


def batch(rollout: int) -> list[PointIn]:
    return [
        PointIn(graph=GRAPH, x={"#dir": "top"}, feasible=False, key=f"run:{rollout}:{i}")
        for i in range(2)
    ]


def test_batches_handed_over_while_the_poster_lingers_go_in_one_request() -> None:
    post = Recorded()
    poster = PointPoster(post, linger_s=LONG)
    for rollout in range(5):
        poster.submit(batch(rollout))
    poster.close()
    assert post.requests == [[f"run:{r}:{i}" for r in range(5) for i in range(2)]]
    assert poster.posted == 10 and poster.done == 5


def test_waiting_for_a_batch_sends_it_without_waiting_out_the_linger() -> None:
    post = Recorded()
    poster = PointPoster(post, linger_s=LONG)
    number = poster.submit(batch(0))
    started = time.monotonic()
    poster.wait_for(number)
    assert time.monotonic() - started < LONG / 2
    assert post.requests == [["run:0:0", "run:0:1"]]
    poster.submit(batch(1))
    poster.close()
    assert post.requests[1:] == [["run:1:0", "run:1:1"]]


def test_without_a_linger_a_batch_goes_as_soon_as_the_poster_is_free() -> None:
    post = Recorded()
    poster = PointPoster(post)
    for rollout in range(3):
        poster.wait_for(poster.submit(batch(rollout)))
    poster.close()
    assert post.requests == [[f"run:{r}:0", f"run:{r}:1"] for r in range(3)]
