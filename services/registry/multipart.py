"""A small, strict `multipart/form-data` reader for version uploads (RFC 7578).

Why not python-multipart: it is not a dependency of coexist, and an upload here is three parts of
bounded size that are read whole into memory anyway (after the size check of the router). Parts
are split on the boundary, which by definition never occurs inside a part; headers are parsed with
the standard library's email parser. A malformed body is an `InvalidArgument` naming `body`.
"""

from __future__ import annotations

from dataclasses import dataclass
from email.message import Message
from email.parser import HeaderParser

from model_store.errors import InvalidArgument


@dataclass(frozen=True)
class Part:
    name: str
    filename: str | None
    content_type: str | None
    data: bytes


def _malformed(why: str) -> InvalidArgument:
    return InvalidArgument(f"body: malformed multipart/form-data ({why})", field="body")


def boundary_of(content_type: str) -> bytes | None:
    """The boundary of a `multipart/form-data` content type, or None for another type."""
    header = Message()
    header["content-type"] = content_type
    if header.get_content_type() != "multipart/form-data":
        return None
    boundary = header.get_param("boundary")
    if not isinstance(boundary, str) or not 1 <= len(boundary) <= 70:
        raise _malformed("missing or invalid boundary")
    return boundary.encode("latin-1")


def parse_form_data(boundary: bytes, body: bytes) -> dict[str, Part]:
    """Parts by field name; a repeated field name is an error."""
    chunks = (b"\r\n" + body).split(b"\r\n--" + boundary)
    if len(chunks) < 2 or not chunks[-1].startswith(b"--"):
        raise _malformed("no closing boundary: the body is truncated")
    parts: dict[str, Part] = {}
    for chunk in chunks[1:-1]:
        line_end = chunk.find(b"\r\n")
        if line_end < 0 or chunk[:line_end].strip(b" \t"):
            raise _malformed("boundary line not followed by CRLF")
        rest = chunk[line_end + 2 :]
        if rest.startswith(b"\r\n"):
            head, data = b"", rest[2:]
        else:
            sep = rest.find(b"\r\n\r\n")
            if sep < 0:
                raise _malformed("part headers not terminated")
            head, data = rest[:sep], rest[sep + 4 :]
        headers = HeaderParser().parsestr(head.decode("latin-1"))
        if headers.get_content_disposition() != "form-data":
            raise _malformed("a part without Content-Disposition: form-data")
        name = headers.get_param("name", header="content-disposition")
        if not isinstance(name, str) or not name:
            raise _malformed("a part without a name")
        if name in parts:
            raise InvalidArgument(f"{name}: the field is given twice", field=name)
        filename = headers.get_filename()
        parts[name] = Part(name, filename, headers.get("content-type"), data)
    return parts
