"""docker-compose.yml: the services a lab needs, commands the CLI really has, settings it reads."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml

from cpkb.cli import build_parser
from server.settings import Settings

ROOT = Path(__file__).resolve().parents[1]
COMPOSE = ROOT / "docker-compose.yml"
_VAR = re.compile(r"\$\{(\w+)(?::?([-?])([^}]*))?\}|\$(\w+)")
# Values for the variables compose requires (`${X:?...}`) when the file is interpolated here.
REQUIRED_VALUES = {"CPKB_TOKEN": "example-token", "CPKB_DB_PASSWORD": "example-password"}
# The service's replicas, and the URLs workers are given (they fail over from one to the other).
REPLICAS = ("kb", "kb2")
REPLICA_URLS = "http://kb:8000,http://kb2:8000"


def interpolate(text: str) -> str:
    """Compose's interpolation with an empty host environment: defaults apply."""

    def one(match: re.Match[str]) -> str:
        name = match.group(1) or match.group(4)
        if match.group(2) == "?":
            return REQUIRED_VALUES[name]
        return match.group(3) or ""

    return _VAR.sub(one, text.replace("$$", "\x00")).replace("\x00", "$")


def _interpolate_tree(node: Any) -> Any:
    if isinstance(node, str):
        return interpolate(node)
    if isinstance(node, list):
        return [_interpolate_tree(item) for item in node]
    if isinstance(node, dict):
        return {key: _interpolate_tree(value) for key, value in node.items()}
    return node


@pytest.fixture(scope="module")
def compose() -> dict[str, Any]:
    return _interpolate_tree(yaml.safe_load(COMPOSE.read_text()))


@pytest.fixture(scope="module")
def services(compose: dict[str, Any]) -> dict[str, Any]:
    return compose["services"]


def _cpkb_services(services: dict[str, Any]) -> dict[str, Any]:
    return {name: svc for name, svc in services.items() if svc.get("image", "").startswith("cpkb")}


def _environment(service: dict[str, Any]) -> dict[str, str]:
    env = service.get("environment", {})
    if isinstance(env, list):
        return dict(item.split("=", 1) for item in env)
    return {key: str(value) for key, value in env.items()}


def _planner_invocations(service: dict[str, Any]) -> list[list[str]]:
    """The `cpkb` commands the worker's loop script runs, with the compose arguments filled in."""
    command = service["command"]
    assert command[:2] == ["sh", "/app/deploy/planner-loop.sh"]
    kb_url, kb, tasks, method, runs, max_rollouts = command[2:]
    assert int(runs) >= 1 and int(max_rollouts) >= 1
    script = (ROOT / "deploy" / "planner-loop.sh").read_text()
    values = {
        "kb_url": kb_url,
        "kb": kb,
        "method": method,
        "seed": "0",
        "i": "0",
        "max_rollouts": max_rollouts,
    }
    invocations = []
    for task in tasks.split(","):
        values["task"] = task
        for line in script.splitlines():
            words = shlex.split(line, comments=True)
            if words[:1] == ["cpkb"]:
                invocations.append([re.sub(r"\$(\w+)", lambda m: values[m[1]], w) for w in words])
    return invocations


def test_the_lab_services_are_there(services: dict[str, Any]) -> None:
    assert {"db", "migrate", *REPLICAS, "planner", "bench"} <= set(services)
    assert services["db"]["image"].startswith("postgres:")
    assert "pg_isready" in " ".join(services["db"]["healthcheck"]["test"])


def test_the_service_starts_after_a_healthy_database_and_its_migrations(
    services: dict[str, Any],
) -> None:
    assert services["migrate"]["depends_on"]["db"]["condition"] == "service_healthy"
    assert services["migrate"]["command"] == ["cpkb", "db", "upgrade"]
    for name in REPLICAS:
        kb_deps = services[name]["depends_on"]
        assert kb_deps["db"]["condition"] == "service_healthy"
        assert kb_deps["migrate"]["condition"] == "service_completed_successfully"
        assert services[name]["command"][:2] == ["cpkb", "serve"]
        assert "/healthz" in " ".join(services[name]["healthcheck"]["test"])


def test_two_replicas_of_one_service(services: dict[str, Any]) -> None:
    kb, kb2 = (services[name] for name in REPLICAS)
    assert kb["command"] == kb2["command"]
    env, env2 = _environment(kb), _environment(kb2)
    assert env.pop("CPKB_REPLICA_NAME") != env2.pop("CPKB_REPLICA_NAME")
    assert env == env2
    host_ports = {p.split(":")[0] for p in kb["ports"] + kb2["ports"]}
    assert len(host_ports) == 2
    for name in ("planner", "bench"):
        assert set(services[name]["depends_on"]) == set(REPLICAS)


def test_both_reach_the_compose_database_with_its_credentials(services: dict[str, Any]) -> None:
    db_env = _environment(services["db"])
    expected = (
        f"postgresql+psycopg://{db_env['POSTGRES_USER']}:{db_env['POSTGRES_PASSWORD']}"
        f"@db:5432/{db_env['POSTGRES_DB']}"
    )
    for name in ("migrate", *REPLICAS):
        assert _environment(services[name])["CPKB_DATABASE_URL"] == expected


def test_every_command_exists_in_the_cli(services: dict[str, Any]) -> None:
    parser = build_parser()
    commands = [svc["command"] for name, svc in services.items() if name not in {"db", "planner"}]
    commands += _planner_invocations(services["planner"])
    assert len(commands) >= 5
    for command in commands:
        assert command[0] == "cpkb", command
        try:
            args = parser.parse_args(command[1:])
        except SystemExit:
            pytest.fail(f"`{shlex.join(command)}` is not a command the cpkb CLI accepts")
        assert callable(args.handler), command


def test_workers_talk_to_the_service_and_are_scalable(services: dict[str, Any]) -> None:
    for invocation in _planner_invocations(services["planner"]):
        assert invocation[invocation.index("--kb-url") + 1] == REPLICA_URLS
    bench = services["bench"]["command"]
    assert bench[bench.index("--kb-url") + 1] == REPLICA_URLS
    for name in ("planner", "bench"):
        assert "container_name" not in services[name]
        assert "ports" not in services[name]


def test_environment_names_are_ones_the_settings_read(services: dict[str, Any]) -> None:
    prefix = Settings.model_config["env_prefix"]
    known = {prefix + field.upper() for field in Settings.model_fields}
    for name, service in _cpkb_services(services).items():
        for key in _environment(service):
            assert key in known, f"service {name}: {key} is not read by server.settings.Settings"
    for key in _environment(services["db"]):
        assert key.startswith("POSTGRES_"), key


def test_the_dockerfile_copies_what_the_image_runs() -> None:
    dockerfile = (ROOT / "Dockerfile").read_text()
    copied = set(re.findall(r"^COPY (\S+) ", dockerfile, flags=re.MULTILINE))
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    assert packages - {"tests"} <= copied
    assert "deploy" in copied and "pyproject.toml" in copied


def test_docker_compose_accepts_the_file() -> None:
    docker = shutil.which("docker")
    if docker is None:
        pytest.skip("docker is not installed here; the file is validated by the tests above")
    probe = subprocess.run([docker, "compose", "version"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip("the docker compose plugin is not installed here")
    result = subprocess.run(
        [docker, "compose", "-f", str(COMPOSE), "config", "--quiet"],
        capture_output=True,
        text=True,
        env={**REQUIRED_VALUES, "PATH": "/usr/bin:/bin:/usr/local/bin"},
    )
    assert result.returncode == 0, result.stderr


def test_the_workers_run_tasks_that_ship(services: dict[str, Any]) -> None:
    from planner.tasks import list_tasks

    shipped = {task.name for task in list_tasks()}
    planned = {inv[inv.index("--task") + 1] for inv in _planner_invocations(services["planner"])}
    bench = services["bench"]["command"]
    benched = set(bench[bench.index("--tasks") + 1].split(","))
    assert planned and benched
    assert planned | benched <= shipped


def test_secrets_have_no_defaults_and_stay_off_command_lines() -> None:
    raw = yaml.safe_load(COMPOSE.read_text())
    text = COMPOSE.read_text()
    for secret in REQUIRED_VALUES:
        assert re.search(r"\$\{" + secret + r":-", text) is None, f"{secret} has a default"
    for name, service in raw["services"].items():
        command = " ".join(service.get("command", []) if isinstance(service, dict) else [])
        assert "CPKB_TOKEN" not in command and "--token" not in command, name


@pytest.mark.slow
def test_the_planner_worker_is_restarted_when_it_gives_up(services: dict[str, Any]) -> None:
    assert services["planner"]["restart"] in {"on-failure", "unless-stopped", "always"}
