"""`cpkb demo`: knowledge transfer in a few minutes, on the embedded default knowledge base.

For each seed: deskP with cp-bo fills a fresh knowledge base (a short budget, as the paper's
predecessor tasks), then desk with cp-bo on the same knowledge base starts from deskP's types,
beside desk with quasi-random-restarts, the strongest search without learning. The rollouts to
the first feasible binding list are shown side by side, with where to look next.
"""

from __future__ import annotations

import os
import shutil
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from planner.display import live_progress
from planner.result import PlanResult
from planner.run import run_plan

BASELINE = "quasi-random-restarts"  # the baseline of every claim (quasi-random with restarts)


def _run(console: Console, label: str, **kwargs: Any) -> PlanResult:
    with live_progress(label, kwargs.get("max_rollouts", 2000), console) as progress:
        return run_plan(progress=progress, **kwargs)


def run_demo(
    kb_url: str,
    *,
    seeds: int = 3,
    predecessor_rollouts: int = 30,
    prefix: str = "",
    embedded: bool = False,
    db: str | None = None,
) -> int:
    """`prefix` selects the worlds: "" for the PyBullet tasks, "analytic:" for the analytic ones;
    the knowledge base is the service at `kb_url`. `embedded`: that service was started for the
    demo on `db` (None: the service's default database) and ends with it, so the next steps
    start one on the same database."""
    console = Console(stderr=True)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    rows: list[tuple[int, str, PlanResult, PlanResult, PlanResult]] = []
    console.print(
        "[bold]cpkb demo[/]: deskP then desk with cp-bo on one knowledge base, "
        f"beside desk with {BASELINE}"
    )
    for seed in range(seeds):
        kb = f"demo-{stamp}-seed{seed}"
        common = {"seed": seed, "kb_url": kb_url, "kb": kb}
        learn = _run(
            console,
            f"seed {seed} deskP cp-bo",
            task=f"{prefix}deskP",
            method="cp-bo",
            max_rollouts=predecessor_rollouts,
            stop_at_first=False,
            **common,
        )
        guided = _run(
            console, f"seed {seed} desk  cp-bo", task=f"{prefix}desk", method="cp-bo", **common
        )
        baseline = _run(
            console,
            f"seed {seed} desk  {BASELINE}",
            task=f"{prefix}desk",
            method=BASELINE,
            seed=seed,
        )
        rows.append((seed, kb, learn, guided, baseline))
    out = Console()
    out.print(_table(rows))
    cp_mean = statistics.mean(r[3].rollouts for r in rows)
    qr_mean = statistics.mean(r[4].rollouts for r in rows)
    out.print(
        f"desk: cp-bo after deskP needs [bold]{cp_mean:.1f}[/] rollouts on average, {BASELINE} "
        f"[bold]{qr_mean:.1f}[/] ({_change(cp_mean, qr_mean)} with knowledge; a few seeds are "
        "a taste, `cpkb bench` measures)."
        if qr_mean > 0
        else ""
    )
    last_kb = rows[-1][1]
    cpkb = _command()
    serve = f"{cpkb} serve --db {db}" if db else f"{cpkb} serve"
    url = "http://127.0.0.1:8000" if embedded else kb_url
    out.print(
        "\n[bold]Where to look next[/]\n"
        f"  {serve + ', then ' if embedded else ''}open {url}/ "
        "(types, causal graphs, points, feasibility maps)\n"
        f"  {cpkb} types --kb-url {url} --kb {last_kb}   the types deskP and desk learned\n"
        f"  {cpkb} plan --task regrasp --method cp-bo --kb-url {url} --kb {last_kb}\n"
        f"  {cpkb} bench --tasks desk --methods {BASELINE},cp-bo,cp-bo-transfer --seeds 20 "
        "--out bench-out"
    )
    return 0 if all(r[3].solved and r[4].solved for r in rows) else 1


def _command() -> str:
    """`cpkb` as this shell can run it: the bare name where it is on PATH (an active venv),
    else the path of the program that is running (`make demo` runs `.venv/bin/cpkb`)."""
    running = Path(sys.argv[0]).resolve()
    on_path = shutil.which("cpkb")
    if on_path is not None and Path(on_path).resolve() == running:
        return "cpkb"
    if running.name == "cpkb":
        return os.path.relpath(running) if running.is_relative_to(Path.cwd()) else str(running)
    return "cpkb"


def _table(rows: list[tuple[int, str, PlanResult, PlanResult, PlanResult]]) -> Table:
    table = Table(title="rollouts to the first feasible binding list")
    for column in ("seed", "deskP cp-bo", "desk cp-bo", f"desk {BASELINE}", "from deskP"):
        table.add_column(column, justify="right")
    for seed, _, learn, guided, baseline in rows:
        table.add_row(
            str(seed),
            f"{learn.rollouts_spent} ({learn.knowledge.points_posted} pts)",
            _cell(guided),
            _cell(baseline),
            f"{guided.knowledge.types_activated} types, {guided.knowledge.points_activated} pts",
        )
    return table


def _cell(result: PlanResult) -> str:
    mark = "" if result.solved else " (unsolved)"
    return f"{result.rollouts}{mark}  {result.wall_s:.1f} s"


def _change(guided: float, baseline: float) -> str:
    """`42% fewer` or `29% more`: the guided mean against the baseline's."""
    change = 1 - guided / baseline
    return f"{abs(change):.0%} {'fewer' if change >= 0 else 'more'}"
