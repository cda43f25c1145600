"""The surrogate knobs: one definition each (`surrogate.config`, and the service's own in
`server.settings.ServiceSurrogateConfig`), set through nested environment variables, and what
the engine runs with."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from server.app import create_app
from server.settings import ServiceSurrogateConfig, Settings, surrogate_overrides
from surrogate.config import OptimizerConfig

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("server", "surrogate", "planner", "cpkb", "client", "migrations")
HOMES = {
    ("surrogate/config.py", "SurrogateConfig"),
    ("surrogate/config.py", "OptimizerConfig"),
    ("server/settings.py", "ServiceSurrogateConfig"),
}
# The names these knobs went by in the copies they replaced.
RETIRED = {"n_gen", "margin", "margin_abs", "walls", "fit_in_child_process", "fit_threads"}


def _class_fields() -> list[tuple[str, str, str, ast.expr | None]]:
    """(file, class, field, default) of every annotated class attribute of the packages."""
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            where = path.relative_to(ROOT).as_posix()
            for node in ast.walk(ast.parse(path.read_text())):
                if not isinstance(node, ast.ClassDef):
                    continue
                for statement in node.body:
                    if isinstance(statement, ast.AnnAssign) and isinstance(
                        statement.target, ast.Name
                    ):
                        found.append((where, node.name, statement.target.id, statement.value))
    return found


def test_each_surrogate_knob_has_one_definition() -> None:
    """Elsewhere a knob's name is a wire field (no default) or takes its default from here."""
    knobs = set(ServiceSurrogateConfig.model_fields) | set(OptimizerConfig.model_fields)
    fields = _class_fields()
    homes = {name: (where, cls) for where, cls, name, _ in fields if (where, cls) in HOMES}
    assert set(homes) == knobs
    copies = [
        f"{where}: {cls}.{name} = {ast.unparse(default)}"
        for where, cls, name, default in fields
        if name in knobs
        and (where, cls) not in HOMES
        and default is not None
        and "Config()." not in ast.unparse(default)
    ]
    assert copies == []
    drifted = [
        f"{where}: {cls}.{name}"
        for where, cls, name, _ in fields
        if cls.endswith(("Config", "Settings"))
        and (name in RETIRED or (name.startswith("surrogate_") and name[10:] in knobs))
    ]
    assert drifted == []


def test_nested_environment_variables_set_the_engines_knobs(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("CPKB_SURROGATE__INSTANT_FIT_POINTS", "7")
    monkeypatch.setenv("CPKB_SURROGATE__OPTIMIZER__GENERATIONS", "3")
    monkeypatch.setenv("CPKB_SURROGATE__FIT_PROCESS", "false")
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'kb.db'}")
    assert settings.surrogate.instant_fit_points == 7
    assert settings.surrogate.optimizer.generations == 3
    assert settings.surrogate.optimizer.pop_size == OptimizerConfig().pop_size
    engine = create_app(settings).state.surrogates
    assert engine.config.instant_fit_points == 7 and not engine.config.fit_process
    assert engine.config.optimizer.generations == 3
    assert surrogate_overrides() == {
        "surrogate.instant_fit_points": 7,
        "surrogate.fit_process": False,
        "surrogate.optimizer.generations": 3,
    }


def test_a_knob_out_of_its_bounds_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CPKB_SURROGATE__OPTIMIZER__POP_SIZE", "2")
    with pytest.raises(ValueError, match=r"surrogate\.optimizer\.pop_size"):
        Settings()
