"""The multipart/form-data reader of the upload endpoint, against httpx's encoder."""

from __future__ import annotations

import httpx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from model_store.errors import InvalidArgument
from services.registry.multipart import boundary_of, parse_form_data


def _encode(files: dict, data: dict) -> tuple[bytes, bytes]:
    request = httpx.Request("POST", "http://x/", files=files, data=data)
    body = request.read()
    boundary = boundary_of(request.headers["content-type"])
    assert boundary is not None
    return boundary, body


@settings(max_examples=60, deadline=None)
@given(weights=st.binary(max_size=2000), spec=st.text(max_size=200))
def test_round_trips_any_bytes(weights: bytes, spec: str) -> None:
    boundary, body = _encode({"weights": ("w.safetensors", weights)}, {"spec": spec})
    parts = parse_form_data(boundary, body)
    assert parts["weights"].data == weights
    assert parts["weights"].filename == "w.safetensors"
    assert parts["spec"].data == spec.encode()


def test_binary_that_looks_like_a_delimiter_is_kept() -> None:
    tricky = b"\r\n--\r\n\r\n--xyz\x00\xff" * 10
    boundary, body = _encode({"weights": ("w", tricky)}, {"spec": "{}"})
    assert parse_form_data(boundary, body)["weights"].data == tricky


def test_content_types_and_malformed_bodies() -> None:
    assert boundary_of("application/json") is None
    assert boundary_of('multipart/form-data; boundary="a b"') == b"a b"
    with pytest.raises(InvalidArgument):
        boundary_of("multipart/form-data")
    boundary, body = _encode({"weights": ("w", b"123")}, {"spec": "{}"})
    for broken in (body[:-5], body.replace(b"form-data; ", b"attachment; ", 1), b""):
        with pytest.raises(InvalidArgument) as err:
            parse_form_data(boundary, broken)
        assert err.value.field == "body"
    twice = body.replace(b'name="weights"', b'name="spec"')
    with pytest.raises(InvalidArgument) as err:
        parse_form_data(boundary, twice)
    assert err.value.field == "spec"
