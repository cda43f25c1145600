"""Core lists as Linux writes them, and the cores a service may take beside its planners."""

from __future__ import annotations

import os

import pytest

from server.cpus import format_cpu_list, parse_cpu_list, spare_cores


@pytest.mark.parametrize(
    ("text", "cores"),
    [("1", {1}), ("1-3", {1, 2, 3}), ("0, 2-3", {0, 2, 3}), ("5,1", {1, 5}), ("2-2", {2})],
)
def test_a_core_list_reads_and_writes_back(text: str, cores: set[int]) -> None:
    assert parse_cpu_list(text) == cores
    assert parse_cpu_list(format_cpu_list(cores)) == cores


def test_ranges_are_written_short() -> None:
    assert format_cpu_list({0, 2, 3, 4, 7}) == "0,2-4,7"


@pytest.mark.parametrize("text", ["", "a", "1-", "3-1", "-1", "1,,2", "1.5"])
def test_a_bad_core_list_names_its_part(text: str) -> None:
    with pytest.raises(ValueError, match="core"):
        parse_cpu_list(text)


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity here")
def test_the_spare_cores_are_those_beyond_the_planners() -> None:
    allowed = sorted(os.sched_getaffinity(0))
    assert spare_cores(0) is None
    assert spare_cores(len(allowed)) is None
    if len(allowed) > 1:
        assert spare_cores(1) == frozenset(allowed[1:])
