"""Server addresses: the one parser of the SDK's clients and of the `coexist` command line.

| written                        | protocol | TLS | what the transport gets            |
|--------------------------------|----------|-----|------------------------------------|
| `http://host[:port][/path]`    | REST     | no  | the URL as written (no trailing /) |
| `https://host[:port][/path]`   | REST     | yes | the URL as written                 |
| `grpc://host:port`             | gRPC     | no  | `host:port`                        |
| `grpcs://host:port`            | gRPC     | yes | `host:port`                        |
| `unix:/path`, `unix:///path`   | gRPC     | no  | the target as written (a socket)   |
| `host:port` (or `host`)        | the one asked for, else REST | no | `http://host:port` or `host:port` |

A bare `host:port` takes the protocol its caller names (`protocol=`, `--transport`, or a client
that speaks one protocol only: `GrpcCoexistClient`, `RegistryClient` ...); where nothing names
one it is REST, the protocol of the default address `http://127.0.0.1:8000`, so
`Client("localhost:8000")` and `coexist run --server localhost:8000` mean the same server. An
address whose scheme contradicts the protocol asked for (`RegistryClient("grpc://...")`: the
registry speaks REST only), or that cannot be an address at all, is a `ValueError` that says
what was expected: a mistake, never a retryable "unavailable".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal
from urllib.parse import urlsplit

Protocol = Literal["http", "grpc"]
DEFAULT_PROTOCOL: Protocol = "http"
EXPECTED = "http(s)://host[:port], grpc(s)://host:port, unix:/path or host:port"
SCHEMES: dict[str, tuple[Protocol, bool]] = {
    "http": ("http", False),
    "https": ("http", True),
    "grpc": ("grpc", False),
    "grpcs": ("grpc", True),
}


@dataclass(frozen=True)
class ServerAddress:
    """A parsed address: `protocol`, whether it asked for `tls`, and `target`, what the
    transport dials (an http(s) base URL for REST; `host:port` or `unix:...` for gRPC)."""

    protocol: Protocol
    tls: bool
    target: str


def parse_address(text: str, protocol: Protocol | None = None) -> ServerAddress:
    """Parse `text` (module docstring's table); `protocol`: the one the caller speaks or asks
    for (None: the scheme decides, REST for a bare `host:port`)."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"server address: empty; expected {EXPECTED}")
    written = text.strip()
    if protocol not in (None, "http", "grpc"):
        raise ValueError(f"protocol: expected 'http' or 'grpc', got {protocol!r}")
    if written.startswith("unix:"):
        _require(written, "grpc", protocol)
        if not written.removeprefix("unix:").lstrip("/"):
            raise ValueError(f"server address {written!r}: a unix socket needs a path")
        return ServerAddress("grpc", False, written)
    if "://" in written:
        scheme = written.split("://", 1)[0].lower()
        if scheme not in SCHEMES:
            raise ValueError(
                f"server address {written!r}: unknown scheme {scheme + '://'!r}; expected "
                f"{EXPECTED}"
            )
        kind, tls = SCHEMES[scheme]
        _require(written, kind, protocol)
        host, port, path = _parts(written)
        if kind == "http":
            return ServerAddress("http", tls, f"{scheme}://{_netloc(host, port)}{path}")
        if path not in ("", "/"):
            raise ValueError(f"server address {written!r}: a gRPC address has no path")
        if port is None:
            raise ValueError(f"server address {written!r}: a gRPC address needs a port")
        return ServerAddress("grpc", tls, _netloc(host, port))
    kind = protocol or DEFAULT_PROTOCOL
    host, port, path = _parts(f"{kind}://{written}")
    if path not in ("", "/"):
        raise ValueError(f"server address {written!r}: expected {EXPECTED}")
    if kind == "http":
        return ServerAddress("http", False, f"http://{_netloc(host, port)}")
    if port is None:
        raise ValueError(f"server address {written!r}: a gRPC address needs a port")
    return ServerAddress("grpc", False, _netloc(host, port))


def _require(written: str, kind: Protocol, asked: Protocol | None) -> None:
    if asked is not None and asked != kind:
        speaks = {"http": "REST (http:// or https://)", "grpc": "gRPC (grpc:// or grpcs://)"}
        raise ValueError(
            f"server address {written!r} is a {kind} address, but this client speaks "
            f"{speaks[asked]}"
        )


def _parts(url: str) -> tuple[str, int | None, str]:
    """(host, port or None, path without a trailing slash) of a URL with a scheme."""
    try:
        split = urlsplit(url)
        port = split.port  # a ValueError for a port that is not a number in 0-65535
    except ValueError as err:
        raise ValueError(f"server address {url!r}: {err}; expected {EXPECTED}") from None
    host = split.hostname
    if not host or split.query or split.fragment or split.username or split.password:
        raise ValueError(f"server address {url!r}: expected {EXPECTED}")
    if port == 0:
        raise ValueError(f"server address {url!r}: port 0 is not a server's port")
    return host, port, split.path.rstrip("/")


def _netloc(host: str, port: int | None) -> str:
    bracketed = f"[{host}]" if ":" in host else host  # an IPv6 literal
    return bracketed if port is None else f"{bracketed}:{port}"
