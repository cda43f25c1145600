"""Generated task suites: random tabletop workspaces, each with a desk-like, a regrasp-like and
a pack-like target and their predecessors, every target checked solvable and not trivial; or,
`generate_hard_suite`, the hard family's, every target checked solvable and hard.

`generate_suite(Path("suite"), workspaces=4, seed=1000)` writes the files; `cpkb generate`
is the command.
"""

from planner.tasks.generator.hard import HardProbe
from planner.tasks.generator.suite import (
    SUITE_FILE,
    GenerationError,
    ProbeSettings,
    generate_hard_suite,
    generate_suite,
)

__all__ = [
    "SUITE_FILE",
    "GenerationError",
    "HardProbe",
    "ProbeSettings",
    "generate_hard_suite",
    "generate_suite",
]
