"""A model store backend for coexist's plugin tests, picked by the URL scheme `tinyline`:
`tinyline:///PATH` keeps its models in the SQLite file PATH through coexist's SQL store, and
every process that opens it appends a line to PATH + ".opened" (its process id and command), so
a test can see which processes picked this backend by its scheme."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from model_store.errors import InvalidArgument
from model_store.sql import SqlModelStore

SCHEME = "tinyline://"


class TinylineStore(SqlModelStore):
    def __init__(self, url: str, **options: Any) -> None:
        if not url.startswith(SCHEME) or not url.removeprefix(SCHEME):
            raise InvalidArgument(
                f"store_url: expected {SCHEME}/PATH, got {url!r}", field="store_url"
            )
        self.path = Path(url.removeprefix(SCHEME)).absolute()
        super().__init__(f"sqlite:///{self.path}", **options)
        with open(f"{self.path}.opened", "a") as log:
            log.write(f"{os.getpid()} {' '.join(sys.argv[1:4])}\n")

    def reopen_url(self) -> str:
        return f"{SCHEME}{self.path}"

    def __repr__(self) -> str:
        return f"TinylineStore({self.reopen_url()!r})"


def open_tinyline_store(url: str, **options: Any) -> TinylineStore:
    """The `coexist.stores` factory of the scheme `tinyline`."""
    return TinylineStore(url, **options)
