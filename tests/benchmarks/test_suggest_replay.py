"""benchmarks/suggest_replay.py: requests recorded from real transfer runs answer again alike."""

from __future__ import annotations

import re

import pytest
from script_support import load_script


@pytest.mark.slow
def test_recorded_requests_replay_to_the_same_answers_every_time(tmp_path, capsys):
    replay = load_script("suggest_replay")
    recording = tmp_path / "requests.pkl"
    assert (
        replay.main(
            ["record", "--tasks", "analytic:desk", "--seeds", "3-4", "--out", str(recording)]
        )
        == 0
    )
    recorded = int(re.search(r"recorded (\d+) requests", capsys.readouterr().out).group(1))
    assert recorded > 0
    digests = []
    for _ in range(2):
        assert replay.main(["replay", str(recording), "--repeats", "2"]) == 0
        out = capsys.readouterr().out
        assert f"{recorded} requests; ms per request by pass:" in out
        digests.append(re.search(r"answers digest (\w+)", out).group(1))
    assert digests[0] == digests[1]


def test_a_missing_recording_or_a_bad_repeat_count_is_a_clear_error(tmp_path, capsys):
    replay = load_script("suggest_replay")
    assert replay.main(["replay", str(tmp_path / "none.pkl")]) == 2
    assert "no such recording" in capsys.readouterr().err
    (tmp_path / "r.pkl").write_bytes(b"")
    assert replay.main(["replay", str(tmp_path / "r.pkl"), "--repeats", "0"]) == 2
    assert "--repeats must be at least 1" in capsys.readouterr().err
