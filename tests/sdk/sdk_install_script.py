"""Run by test_sdk_install.py inside a fresh virtual environment holding only the built
`coexist-client` wheel and its four dependencies: act, a session and a registry promote against
a real server, printed as one JSON object.

    python sdk_install_script.py HTTP_URL GRPC_TARGET ADMIN_TOKEN
"""

from __future__ import annotations

import importlib.util
import json
import sys

from coexist_client import Client, RegistryClient

OBS = [0.1, 0.5, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]


def main(http_url: str, grpc_target: str, token: str) -> dict[str, object]:
    absent = [
        m
        for m in ("torch", "fastapi", "sqlalchemy", "services", "model_store")
        if importlib.util.find_spec(m) is not None
    ]
    out: dict[str, object] = {"server_modules_found": absent}
    with Client(http_url) as http, Client(f"grpc://{grpc_target}") as grpc:
        out["act_http"] = list(http.act("particle", "a2", OBS, partners={1: "b3"}, seed=7).probs)
        out["act_grpc"] = list(grpc.act("particle", "a2", OBS, partners={1: "b3"}, seed=7).probs)
        with http.session("particle", "a2", partners={1: None}, seed=0) as session:
            session.step(OBS)
            step = session.step(OBS, observed={1: 2})
            out["session"] = {"step": step.step, "updates": step.beliefs[0].updates}
    with RegistryClient(http_url, token=token) as registry:
        out["promoted"] = registry.promote("particle/task/a2", 2, alias="production")
        out["resolved"] = registry.resolve("particle/task/a2@production").version
    return out


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:4])))
