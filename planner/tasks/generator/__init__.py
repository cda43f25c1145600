"""Generated task suites: random tabletop workspaces, each with a desk-like, a regrasp-like and
a pack-like target and their predecessors, every target checked solvable and not trivial.

`generate_suite(Path("suite"), workspaces=4, seed=1000)` writes the files; `cpkb generate`
is the command.
"""

from planner.tasks.generator.suite import (
    SUITE_FILE,
    GenerationError,
    ProbeSettings,
    generate_suite,
)

__all__ = ["SUITE_FILE", "GenerationError", "ProbeSettings", "generate_suite"]
