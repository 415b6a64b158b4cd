"""A TCP relay whose upstream connections leave from another loopback address, so that a test can
be several clients (127.0.0.2, 127.0.0.3, ...) to a server on 127.0.0.1: Linux picks 127.0.0.1
as the source of every loopback connection a client does not bind itself, and gRPC's channels
cannot bind one (imported by the tests; not a test module).

    with SourceProxy("127.0.0.2", ("127.0.0.1", port)) as proxy:
        grpc.insecure_channel(proxy.target)   # the server sees peer ipv4:127.0.0.2:...
"""

from __future__ import annotations

import socket
import threading
from types import TracebackType


class SourceProxy:
    def __init__(self, source_ip: str, upstream: tuple[str, int]) -> None:
        self.source_ip, self.upstream = source_ip, upstream
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.target = f"127.0.0.1:{self._listener.getsockname()[1]}"
        self._sockets: list[socket.socket] = []
        self._closed = False
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            server = socket.create_connection(self.upstream, source_address=(self.source_ip, 0))
            self._sockets += [client, server]
            for source, sink in ((client, server), (server, client)):
                threading.Thread(target=_pump, args=(source, sink), daemon=True).start()

    def __enter__(self) -> SourceProxy:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, err: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._closed = True
        self._listener.close()
        for sock in self._sockets:
            sock.close()


def _pump(source: socket.socket, sink: socket.socket) -> None:
    try:
        while data := source.recv(65536):
            sink.sendall(data)
        sink.shutdown(socket.SHUT_WR)
    except OSError:
        pass
