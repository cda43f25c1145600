"""Towers of Hanoi posed by its goal alone: with `stacking: towers` the domain puts a body only
on a larger one (static `smaller` facts from the bodies' sizes) and a region holds one tower."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from planner.goals.pddl import domain, problem, top_plans
from planner.tasks import load_task
from planner.tasks.schema import smaller

HANOI = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "external" / "hanoi"


def test_smaller_facts_come_from_the_sizes() -> None:
    task = load_task(str(HANOI / "hanoi3.yaml"))
    assert task.stacking == "towers"
    text = problem(task)
    for fact in ("(smaller d1 d2)", "(smaller d1 d3)", "(smaller d2 d3)"):
        assert fact in text
    for wrong in ("(smaller d3 d1)", "(smaller d2 d1)", "(smaller d3 d2)", "(smaller d1 d1)"):
        assert wrong not in text
    body = task.bodies
    assert smaller(body["d1"], body["d2"]) and not smaller(body["d2"], body["d2"])
    # Side for side: a long thin body is not smaller than a square one, though less in area.
    thin = replace(body["d1"], size=(0.02, 0.05, 0.04))
    assert not smaller(thin, body["d2"])


def test_only_towers_rules_constrain_stacking() -> None:
    towers, free = domain("towers"), domain("free")
    assert (
        "(clear ?s) (smaller ?b ?s)" in towers
        and "(smaller ?b ?s)" not in free.split(":action stack")[1]
    )
    assert "(free ?r)" in towers.split(":action place")[1]
    assert "(free ?r)" not in free.split(":action pick")[1]
    text = problem(load_task(str(HANOI.parent / "blocked" / "blocked.yaml")))
    assert "smaller" not in text and "free" not in text


def test_k_star_solves_hanoi_in_seven_moves_never_a_disc_on_a_smaller_one() -> None:
    task = load_task(str(HANOI / "hanoi3.yaml"))
    plans = top_plans(task, 40)
    assert len(plans[0].moves) == 7
    for plan in plans:
        for move in plan.moves:
            if move.place in task.bodies:
                assert smaller(task.bodies[move.body], task.bodies[move.place]), plan
