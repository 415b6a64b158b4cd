"""docker/ tested without a Docker engine (none runs on this machine).

- compose.yaml parses (PyYAML) into the topology: PostgreSQL with a health check, a one-shot
  migration, the trainer job, two inference replicas sharing their REST sessions through a
  password-protected Redis, a load balancer for HTTP and gRPC;
- every command the images run is a `coexist` command whose options the CLI accepts;
- the Dockerfile: multi-stage, non-root, CPU torch by default, CUDA documented, health checks,
  and its COPY list holds every package pyproject ships;
- Envoy's config sends both listeners to the replicas' ports;
- monitoring: Prometheus scrapes every replica's /metrics (by the service's DNS name), Grafana
  is provisioned with that Prometheus and a dashboard whose every query names a metric the
  server exports (checked against the replicas of the process topology below);
- the same topology as plain processes, running what the images install (a wheel built from the
  Dockerfile's COPY list, not this checkout): PostgreSQL (a fresh schema), the migration command,
  the trainer command (`--help`: a real zoo takes tens of minutes; a tiny registered zoo stands
  in for its result), two replicas from the compose command, the image's HEALTHCHECK against
  one, and REST and gRPC requests through a round-robin TCP proxy standing in for Envoy (nginx
  and Envoy are not installed here), a REST session among them, stepped on both replicas
  through the compose file's session settings (a local Redis standing in for the `redis` one).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path
from typing import Any

import httpx
import pytest
import yaml
from docker_files import (
    DOCKER,
    REPO,
    RoundRobinProxy,
    dockerfile_stages,
    interpolate,
    parse_coexist,
    service_argv,
)

sys.path.insert(0, str(REPO / "tests" / "services"))  # the serve-process helpers
from coexist_client import GrpcCoexistClient
from coexist_client.sessions import AFFINITY_HEADER
from replica_cluster import (
    ADMIN_TOKEN,
    OBS,
    act_body,
    pg_schema_url,
    running,
    seed_zoo,
    server_env,
    start_server,
)
from session_backends import drop_namespace, redis_url

from services.sessions.codec import SessionCodec

COMPOSE = yaml.safe_load((DOCKER / "compose.yaml").read_text())
SERVICES: dict[str, Any] = COMPOSE["services"]
STAGES = dockerfile_stages()
OUR_IMAGES = {name: s for name, s in SERVICES.items() if "build" in s}


def _depends(service: str) -> dict[str, str]:
    return {k: v["condition"] for k, v in SERVICES[service].get("depends_on", {}).items()}


def test_compose_describes_the_topology() -> None:
    assert set(SERVICES) == {
        "postgres",
        "redis",
        "migrate",
        "trainer",
        "inference",
        "lb",
        "prometheus",
        "grafana",
    }
    assert "pg_isready" in " ".join(SERVICES["postgres"]["healthcheck"]["test"])
    assert _depends("migrate") == {"postgres": "service_healthy"}
    assert SERVICES["migrate"]["restart"] == "no"  # one shot
    assert _depends("trainer") == {"migrate": "service_completed_successfully"}
    assert SERVICES["trainer"]["restart"] == "no"  # a job
    assert _depends("inference") == {
        "trainer": "service_completed_successfully",
        "redis": "service_healthy",  # the replicas' shared REST sessions
    }
    assert "redis-cli ping" in " ".join(SERVICES["redis"]["healthcheck"]["test"])
    assert "ports" not in SERVICES["redis"]  # the replicas' alone
    assert SERVICES["inference"]["deploy"]["replicas"] == 2
    assert "ports" not in SERVICES["inference"]  # reached through the load balancer only
    assert _depends("lb") == {"inference": "service_healthy"}
    published = {p.split(":")[-1] for p in SERVICES["lb"]["ports"]}
    assert {"8000", "50051"} <= published
    for volume in SERVICES["lb"]["volumes"]:
        assert (DOCKER / volume.split(":")[0]).is_file()
    for name, service in OUR_IMAGES.items():
        assert service["build"]["dockerfile"] == "docker/Dockerfile", name
        assert (DOCKER / service["build"]["context"]).resolve() == REPO
        assert service["build"]["target"] in STAGES, name
        assert "postgresql://" in service["environment"]["COEXIST_STORE_URL"], name
    with pytest.raises(KeyError, match="COEXIST_ADMIN_TOKEN"):  # no default secret
        interpolate(SERVICES["inference"]["environment"], {"POSTGRES_PASSWORD": "pw"})


SECRETS = {
    "POSTGRES_PASSWORD": "pg-secret-for-the-test",
    "COEXIST_ADMIN_TOKEN": "admin-secret-for-the-test",
    "COEXIST_READ_TOKEN": "read-secret-for-the-test",
    "GRAFANA_ADMIN_PASSWORD": "grafana-secret-for-the-test",
    "REDIS_PASSWORD": "redis-secret-for-the-test",
    "COEXIST_SESSION_SECRET": "session-secret-for-the-test",
}


@pytest.mark.parametrize("secret", sorted(SECRETS))
def test_compose_refuses_to_start_without_each_secret(secret: str) -> None:
    """No secret has a default (a default password is a public one): leaving any one unset
    makes compose's interpolation fail, for every service that needs it."""
    given = {k: v for k, v in SECRETS.items() if k != secret}
    needing = [name for name, s in SERVICES.items() if secret in json.dumps(s)]
    assert needing, secret
    for name in needing:
        with pytest.raises(KeyError, match=secret):
            interpolate(SERVICES[name], given)
    everything = interpolate(COMPOSE, SECRETS)  # with all of them set, all of it resolves
    assert (
        everything["services"]["postgres"]["environment"]["POSTGRES_PASSWORD"]
        == (SECRETS["POSTGRES_PASSWORD"])
    )


def test_the_replicas_share_their_sessions_through_a_password_protected_redis() -> None:
    """Every replica has the same session store (the `redis` service, with its password) and
    the same signing secret; Redis reads its password from a config file, never from its
    command line (which `ps` shows), and the health check authenticates from the environment."""
    env = interpolate(SERVICES["inference"]["environment"], SECRETS)
    url = env["COEXIST_SESSION_STORE_URL"]
    assert url == f"redis://:{SECRETS['REDIS_PASSWORD']}@redis:6379/0"
    assert env["COEXIST_SESSION_SECRET"] == SECRETS["COEXIST_SESSION_SECRET"]
    redis = interpolate(SERVICES["redis"], SECRETS)
    (mount,) = redis["configs"]
    assert redis["command"] == ["redis-server", mount["target"]]
    assert SECRETS["REDIS_PASSWORD"] not in json.dumps(redis["command"])
    conf = interpolate(COMPOSE["configs"][mount["source"]]["content"], SECRETS).splitlines()
    assert f"requirepass {SECRETS['REDIS_PASSWORD']}" in conf
    assert redis["environment"]["REDISCLI_AUTH"] == SECRETS["REDIS_PASSWORD"]
    assert any(v.endswith(":/data") for v in redis["volumes"])  # sessions outlive a restart


def test_compose_requires_the_read_token_and_prometheus_sends_it() -> None:
    env = interpolate(SERVICES["inference"]["environment"], SECRETS)
    assert env["COEXIST_REQUIRE_READ_TOKEN"] == "true"
    assert env["COEXIST_READ_TOKEN"] == SECRETS["COEXIST_READ_TOKEN"]
    assert f":{SECRETS['POSTGRES_PASSWORD']}@" in env["COEXIST_STORE_URL"]
    (mount,) = SERVICES["prometheus"]["configs"]
    content = interpolate(COMPOSE["configs"][mount["source"]]["content"], SECRETS)
    assert content == SECRETS["COEXIST_READ_TOKEN"]
    (job,) = yaml.safe_load((DOCKER / "prometheus.yml").read_text())["scrape_configs"]
    assert job["authorization"] == {"type": "Bearer", "credentials_file": mount["target"]}


LEAF_COMMANDS = {
    "migrate": "coexist models migrate",
    "trainer": "coexist train zoo",
    "inference": "coexist serve",
}


@pytest.mark.parametrize("name", sorted(OUR_IMAGES))
def test_every_service_runs_a_command_the_cli_has(name: str) -> None:
    argv = service_argv(SERVICES[name], STAGES)
    context = parse_coexist(argv)  # raises on an unknown sub-command or option
    assert context.info_name == LEAF_COMMANDS[name]
    if name == "inference":  # listens on every interface, never trains on its own
        assert context.params["host"] == "0.0.0.0" and context.params["bootstrap"] is False
        assert (context.params["http_port"], context.params["grpc_port"]) == (8000, 50051)
    if name == "trainer":  # resumable through the trainer-runs volume
        assert context.params["resume"] is True
        assert str(context.params["run_dir"]) in {
            v.split(":")[1] + "/zoo" for v in SERVICES["trainer"]["volumes"]
        }


@pytest.mark.parametrize("target", ["server", "trainer"])
def test_the_images_default_commands_are_cli_commands(target: str) -> None:
    stage = STAGES[target]
    assert stage.entrypoint == ["coexist"] and stage.cmd
    context = parse_coexist([*stage.entrypoint, *stage.cmd])
    assert context.info_name == {"server": "coexist serve", "trainer": "coexist train zoo"}[target]
    with pytest.raises(AssertionError, match="no sub-command 'trian'"):  # the check can fail
        parse_coexist(["coexist", "trian", "zoo"])
    with pytest.raises(Exception, match="No such option"):
        parse_coexist(["coexist", "train", "zoo", "--backend", "ray", "--no-such-option", "2"])


def test_the_dockerfile_builds_small_non_root_images() -> None:
    assert {"build", "runtime", "server", "trainer"} <= set(STAGES)
    assert STAGES["server"].base == "runtime" == STAGES["trainer"].base
    assert STAGES["runtime"].base.startswith("python:")  # not the build stage: no pip caches
    for target in ("server", "trainer"):
        assert STAGES[target].user not in (None, "root", "0", "0:0")
    assert STAGES["build"].args["TORCH_INDEX_URL"].endswith("/whl/cpu")
    assert "whl/cu" in (DOCKER / "Dockerfile").read_text()  # the CUDA variant is documented
    assert STAGES["server"].healthcheck and "/readyz" in STAGES["server"].healthcheck[-1]
    assert STAGES["trainer"].healthcheck == ["NONE"]  # a job: its exit status is its health
    shipped = tomllib.loads((REPO / "pyproject.toml").read_text())
    packages = shipped["tool"]["setuptools"]["packages"]["find"]["include"]
    copied = set(STAGES["build"].copies)
    assert {p.rstrip("*") for p in packages} <= copied, "a package is missing from COPY"
    assert {"pyproject.toml", shipped["project"]["readme"]} <= copied


def _dashboard_metrics() -> set[str]:
    """The metric names the provisioned dashboard's queries read (`_total`, `_bucket` and the
    like kept: they are what the server's /metrics page shows)."""
    dashboard = json.loads((DOCKER / "grafana" / "dashboards" / "coexist.json").read_text())
    exprs = [t["expr"] for p in dashboard["panels"] for t in p["targets"]]
    return {name for e in exprs for name in re.findall(r"\b(coexist_[a-z_]+)", e)}


def test_prometheus_and_grafana_watch_the_replicas() -> None:
    prometheus, grafana = SERVICES["prometheus"], SERVICES["grafana"]
    assert _depends("prometheus") == {"inference": "service_healthy"}
    assert grafana["depends_on"] == ["prometheus"]
    for service in (prometheus, grafana):  # every mounted file or folder exists
        for volume in service["volumes"]:
            source = volume.split(":")[0]
            if source.startswith("./"):
                assert (DOCKER / source).exists(), volume
            else:
                assert source in COMPOSE["volumes"], volume
        assert all(p.startswith("127.0.0.1:") for p in service["ports"])  # local only
    config_mount = next(v for v in prometheus["volumes"] if v.startswith("./prometheus.yml"))
    assert config_mount.split(":")[1] in " ".join(prometheus["command"])
    scrape = yaml.safe_load((DOCKER / "prometheus.yml").read_text())["scrape_configs"]
    (job,) = scrape
    (target,) = job["dns_sd_configs"]
    assert target["names"] == ["inference"] and target["port"] == 8000
    assert job["metrics_path"] == "/metrics" and "8000" in SERVICES["inference"]["expose"]
    with pytest.raises(KeyError, match="GRAFANA_ADMIN_PASSWORD"):  # no default password
        interpolate(grafana["environment"], {})
    provisioning = DOCKER / "grafana" / "provisioning"
    (source,) = yaml.safe_load((provisioning / "datasources" / "prometheus.yaml").read_text())[
        "datasources"
    ]
    port = prometheus["ports"][0].split(":")[-1]
    assert source["url"] == f"http://prometheus:{port}"
    (provider,) = yaml.safe_load((provisioning / "dashboards" / "coexist.yaml").read_text())[
        "providers"
    ]
    mounts = dict(v.split(":")[:2] for v in grafana["volumes"] if v.startswith("./"))
    assert mounts["./grafana/dashboards"] == provider["options"]["path"]
    assert mounts["./grafana/provisioning"] == "/etc/grafana/provisioning"
    dashboard = json.loads((DOCKER / "grafana" / "dashboards" / "coexist.json").read_text())
    uids = {t["datasource"]["uid"] for p in dashboard["panels"] for t in p["targets"]}
    assert uids == {source["uid"]}
    home = grafana["environment"]["GF_DASHBOARDS_DEFAULT_HOME_DASHBOARD_PATH"]
    assert home == f"{provider['options']['path']}/coexist.json"
    assert {"coexist_http_requests_total", "coexist_http_request_seconds_bucket"} <= (
        _dashboard_metrics()
    )


def test_envoy_sends_both_protocols_to_the_replicas() -> None:
    envoy = yaml.safe_load((DOCKER / "envoy.yaml").read_text())
    resources = envoy["static_resources"]
    listeners = {
        lst["address"]["socket_address"]["port_value"]: lst for lst in resources["listeners"]
    }
    assert set(listeners) == {8000, 50051}
    clusters = {c["name"]: c for c in resources["clusters"]}
    serve_argv = service_argv(SERVICES["inference"], STAGES)
    ports = {
        "inference_http": serve_argv[serve_argv.index("--http-port") + 1],
        "inference_grpc": serve_argv[serve_argv.index("--grpc-port") + 1],
    }
    for port, listener in listeners.items():
        manager = listener["filter_chains"][0]["filters"][0]["typed_config"]
        routes = manager["route_config"]["virtual_hosts"][0]["routes"]
        cluster = clusters[routes[-1]["route"]["cluster"]]  # the catch-all "/"
        endpoint = cluster["load_assignment"]["endpoints"][0]["lb_endpoints"][0]["endpoint"]
        address = endpoint["address"]["socket_address"]
        assert address["address"] == "inference" and cluster["type"] == "STRICT_DNS"
        assert str(address["port_value"]) == ports[cluster["name"]]
        assert str(port) == ports[cluster["name"]]  # the LB publishes the replicas' ports
    assert "http2_protocol_options" in str(clusters["inference_grpc"])
    assert clusters["inference_http"]["health_checks"][0]["http_health_check"]["path"] == "/readyz"
    assert "grpc_health_check" in clusters["inference_grpc"]["health_checks"][0]


def test_envoy_keeps_a_session_on_one_replica() -> None:
    envoy = yaml.safe_load((DOCKER / "envoy.yaml").read_text())
    resources = envoy["static_resources"]
    [rest] = [lst for lst in resources["listeners"] if lst["name"] == "rest"]
    manager = rest["filter_chains"][0]["filters"][0]["typed_config"]
    routes = manager["route_config"]["virtual_hosts"][0]["routes"]
    assert routes[0]["match"] == {"prefix": "/v1/sessions"}  # before the catch-all "/"
    route = routes[0]["route"]
    assert route["hash_policy"] == [{"header": {"header_name": AFFINITY_HEADER.lower()}}]
    assert route["retry_policy"]["retry_on"] == "connect-failure"  # a step is not idempotent
    clusters = {c["name"]: c for c in resources["clusters"]}
    sessions, http = clusters[route["cluster"]], clusters["inference_http"]
    assert sessions["lb_policy"] == "RING_HASH"
    assert sessions["load_assignment"]["endpoints"] == http["load_assignment"]["endpoints"]


def _service_env(
    service: str, base: dict[str, str], store_url: str, session_url: str = ""
) -> dict[str, str]:
    """The image's and the compose file's COEXIST_* variables over `base`; the container-only
    ones (data dir, listen address) and the store URLs (no host `postgres` or `redis` here)
    replaced."""
    image = STAGES[SERVICES[service]["build"]["target"]].env
    kept = {
        k: v
        for k, v in image.items()
        if k.startswith("COEXIST_") and k not in ("COEXIST_DATA_DIR", "COEXIST_HOST")
    }
    compose = interpolate(
        SERVICES[service].get("environment", {}), {**SECRETS, "COEXIST_ADMIN_TOKEN": ADMIN_TOKEN}
    )
    env = {**base, **kept, **compose, "COEXIST_STORE_URL": store_url}
    if "COEXIST_SESSION_STORE_URL" in env:
        env["COEXIST_SESSION_STORE_URL"] = session_url
    return env


def _install_like_the_image(tmp_path: Path) -> tuple[list[str], dict[str, str]]:
    """Build coexist from the Dockerfile's COPY list into a wheel and unpack it; returns the
    `coexist` launcher and the PYTHONPATH that make processes import it, not the checkout."""
    import shutil

    source = tmp_path / "src"
    for item in STAGES["build"].copies:
        src = REPO / item
        if src.is_dir():
            shutil.copytree(src, source / item, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            (source / item).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(src, source / item)
    wheels = tmp_path / "wheels"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            str(source),
            "-w",
            str(wheels),
        ],
        check=True,
        capture_output=True,
    )
    site = tmp_path / "site"
    (wheel,) = wheels.glob("coexist-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)
        points = next(n for n in archive.namelist() if n.endswith("entry_points.txt"))
        entry = archive.read(points).decode()
    module, _, attr = entry.split("coexist = ")[1].split()[0].partition(":")
    launcher = [
        sys.executable,
        "-c",
        f"import sys; from {module} import {attr} as main; sys.argv[0] = 'coexist'; main()",
    ]
    return launcher, {"PYTHONPATH": str(site)}


@pytest.mark.postgres
@pytest.mark.redis
@pytest.mark.slow
def test_the_topology_runs_as_plain_processes(tmp_path: Path) -> None:
    launcher, path_env = _install_like_the_image(tmp_path)
    run_dir = tmp_path / "cwd"
    run_dir.mkdir()
    with pg_schema_url() as store_url, redis_url() as session_url:  # postgres, redis: healthy
        base_env = server_env(store_url, tmp_path / "data", **path_env)
        where = subprocess.run(
            [*launcher[:2], "import cli; print(cli.__file__)"],
            env=base_env,
            cwd=run_dir,
            capture_output=True,
            text=True,
            check=True,
        )
        assert where.stdout.startswith(str(tmp_path / "site")), where.stdout

        def run(service: str, *extra: str) -> subprocess.CompletedProcess[str]:
            argv = service_argv(SERVICES[service], STAGES)
            env = _service_env(service, base_env, store_url)
            return subprocess.run(
                [*launcher, *argv[1:], *extra],
                env=env,
                cwd=run_dir,
                capture_output=True,
                text=True,
                timeout=120,
            )

        migrated = run("migrate")
        assert migrated.returncode == 0 and "schema at" in migrated.stdout, migrated.stderr
        trainer_help = run("trainer", "--help")
        assert trainer_help.returncode == 0 and "--backend" in trainer_help.stdout
        seed_zoo(store_url)  # what the trainer job leaves behind, in miniature

        inference = service_argv(SERVICES["inference"], STAGES)[1:]
        env = _service_env("inference", base_env, store_url, session_url)
        replicas = [
            start_server(f"replica-{k}", env, tmp_path, inference, launcher=launcher, cwd=run_dir)
            for k in range(2)
        ]
        read_token = env["COEXIST_READ_TOKEN"]
        read_auth = {"Authorization": f"Bearer {read_token}"}
        with running(replicas):
            health = list(STAGES["server"].healthcheck or [])
            if health[0] == "python":  # the image's interpreter; here, this one
                health[0] = sys.executable
            for server in replicas:  # the image's HEALTHCHECK, as Docker would run it
                port = server.http_url.rsplit(":", 1)[1]
                probe = subprocess.run(health, env={**env, "COEXIST_HTTP_PORT": port})
                assert probe.returncode == 0
            dead = subprocess.run(
                health, env={**env, "COEXIST_HTTP_PORT": "1"}, capture_output=True
            )
            assert dead.returncode != 0

            http_backends = [("127.0.0.1", int(s.http_url.rsplit(":", 1)[1])) for s in replicas]
            grpc_backends = [("127.0.0.1", int(s.grpc_target.rsplit(":", 1)[1])) for s in replicas]
            with (
                RoundRobinProxy(http_backends) as http_lb,
                RoundRobinProxy(grpc_backends) as grpc_lb,
            ):
                lb_act = f"http://127.0.0.1:{http_lb.port}/v1/act"
                anonymous = httpx.post(lb_act, json=act_body())  # reads need the token
                assert anonymous.status_code == 401, anonymous.text
                for k in range(4):  # a new connection each: round robin over the replicas
                    resp = httpx.post(
                        lb_act,
                        json=act_body(),
                        headers={"X-Request-ID": f"through-lb-{k}", **read_auth},
                    )
                    assert resp.status_code == 200 and resp.json()["models"][0]["version"] == 1
                own = [("grpc.use_local_subchannel_pool", 1)]  # no connection shared
                for _ in range(2):
                    with GrpcCoexistClient(
                        f"127.0.0.1:{grpc_lb.port}", options=own, token=read_token
                    ) as client:
                        action = client.act("particle", "a2", OBS, partners={1: "b3"}, seed=1)
                        assert len(action.probs) == 5
                assert http_lb.counts == [3, 2] and grpc_lb.counts == [1, 1]
                # A session created on one replica and stepped on both, round robin: the
                # compose file's shared store and secret at work.
                lb_sessions = f"http://127.0.0.1:{http_lb.port}/v1/sessions"
                try:
                    created = httpx.post(
                        lb_sessions,
                        json={
                            "env": "particle",
                            "ego_goal": "a2",
                            "partners": [{"index": 1, "goal": "b3"}],
                            "seed": 1,
                        },
                        headers=read_auth,
                    )
                    assert created.status_code == 201, created.text
                    session_id = created.json()["session_id"]
                    for step in range(2):
                        answer = httpx.post(
                            f"{lb_sessions}/{session_id}/steps",
                            json={"observation": OBS, "expected_step": step},
                            headers=read_auth,
                            timeout=30,
                        )
                        assert answer.status_code == 200, answer.text
                    assert http_lb.counts == [4, 4]  # created on one, stepped on each
                finally:
                    namespace = SessionCodec(env["COEXIST_SESSION_SECRET"].encode()).namespace()
                    drop_namespace(session_url, namespace)
            for server in replicas:  # what Prometheus scrapes: every dashboard metric is there
                assert httpx.get(f"{server.http_url}/metrics").status_code == 401
                page = httpx.get(f"{server.http_url}/metrics", headers=read_auth).text
                exported = set(re.findall(r"^(coexist_[a-z_]+)", page, flags=re.MULTILINE))
                assert _dashboard_metrics() <= exported, _dashboard_metrics() - exported
        for k, server in enumerate(replicas):
            assert server.process.returncode in (0, -15)
            answered = [line for line in server.logs() if '"through-lb-' in line]
            assert len(answered) == 2, f"replica {k} answered {len(answered)} of 4 REST requests"
