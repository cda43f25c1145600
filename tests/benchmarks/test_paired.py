"""benchmarks/paired.py: arms paired by (target, seed), twin arms averaged, caps for unsolved."""

from __future__ import annotations

import json

import pytest
from script_support import ROOT, load_script

DESK = str(ROOT / "benchmarks" / "suites" / "dev" / "ws00" / "desk.yaml")
PACK = str(ROOT / "benchmarks" / "suites" / "dev" / "ws00" / "pack.yaml")


def _run(task: str, method: str, seed: int, rollouts: int, solved: bool = True) -> dict:
    return {
        "task": task,
        "method": method,
        "seed": seed,
        "rollouts": rollouts,
        "solved": solved,
        "max_rollouts": 100,
    }


def test_arms_are_paired_by_target_and_seed_and_twins_averaged(tmp_path, capsys):
    runs = [
        _run(DESK, "a1", 1, 10),
        _run(DESK, "a2", 1, 30),
        _run(DESK, "b", 1, 10),
        _run(DESK, "a1", 2, 40),
        _run(DESK, "b", 2, 7, solved=False),  # counts as the cap, 100
        _run(PACK, "a1", 1, 5),  # no B run of this pair: left out
    ]
    (tmp_path / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in runs))
    found = load_script("paired").pairs([*runs], ["a1", "a2"], ["b"])
    assert found["desk"] == [(20.0, 10.0), (40.0, 100.0)]
    assert "pack" not in found and found["all"] == found["desk"]
    assert load_script("paired").main([str(tmp_path), "a1+a2", "b"]) == 0
    out = capsys.readouterr().out
    assert "| desk | 2 | 30.0 | 55.0 | 1.83 |" in out


def test_an_empty_results_directory_is_a_clear_error(tmp_path, capsys):
    assert load_script("paired").main([str(tmp_path), "a", "b"]) == 2
    assert "no runs" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        load_script("paired").main([str(tmp_path)])


def test_an_arm_may_come_from_another_benchs_directory(tmp_path, capsys):
    alone, together = tmp_path / "alone", tmp_path / "n8"
    for directory, runs in (
        (alone, [_run(DESK, "cp-bo", 1, 40), _run(DESK, "cp-bo", 2, 20)]),
        (together, [_run(DESK, "cp-bo", 1, 10), _run(DESK, "cp-bo", 3, 5)]),
    ):
        directory.mkdir()
        (directory / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in runs))
    assert load_script("paired").main([str(tmp_path), "alone:cp-bo", "n8:cp-bo"]) == 0
    assert "| desk | 1 | 40.0 | 10.0 | 0.25 |" in capsys.readouterr().out  # seed 1 only


def test_one_arm_is_measured_against_the_strongest_baseline_with_targets_resampled(
    tmp_path, capsys
):
    regrasp = str(ROOT / "benchmarks" / "suites" / "dev" / "ws01" / "regrasp.yaml")
    runs = [
        _run(task, method, seed, rollouts)
        for task, base, guided in ((DESK, 40, 10), (PACK, 20, 30), (regrasp, 60, 15))
        for seed in range(3)
        for method, rollouts in (
            ("quasi-random-restarts", base + seed),
            ("quasi-random", 90),
            ("cp-bo", guided + seed),
        )
    ]
    (tmp_path / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in runs))
    script = load_script("paired")
    found = script.targets(runs, ["quasi-random-restarts"], ["cp-bo"])
    assert len(found["all"]) == 3 and len(found["desk"]) == 1
    assert list(found["desk"][0][0]) == [40, 41, 42]
    assert script.main([str(tmp_path), "cp-bo"]) == 0
    out = capsys.readouterr().out
    assert "A: quasi-random-restarts, B: cp-bo" in out
    everything = next(line for line in out.splitlines() if line.startswith("| all |"))
    cells = [c.strip() for c in everything.split("|")[1:-1]]
    assert cells[:5] == ["all", "9", "41.0", "19.3", "0.47"]
    assert cells[7] == "2/3"  # pack's guided mean is above the baseline's
    low, high = (float(v) for v in cells[6].strip("[]").split(","))
    assert low < 0.47 < high and high - low > 0.2  # three unlike targets: a wide interval
    assert "| desk | 3 |" in out and "| 1/1 |" in out
    assert script.main([str(tmp_path), "quasi-random", "cp-bo"]) == 0
    assert "| all | 9 | 90.0 |" in capsys.readouterr().out
