"""A wedge's scheduler that is not one (issue 36, item 5): nothing listening, a
listener that never answers, an HTTP server (the dashboard's port), an http://
address, a server speaking something else, a host that does not resolve. Each is
one line naming the address and the cause within the connect timeout; an HTTP
server was "out of memory" (Dask read its reply as a frame length) and a silent
listener hung 60 s past a 3 s --connect-timeout."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest
from bad_input import assert_clean_failure, deadline, run_blastvox, unchanged

SCENE = """
[[objects]]
mesh = "box.stl"
voxel_size = 0.5

[[charges]]
position = [0.0, -2.0, 0.5]
mass_kg = 1.0

[simulation]
duration = 0.1

[output]
model = "out/model.npz"
cache = "out/sim.npz"
"""


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    import trimesh

    trimesh.creation.box().export(tmp_path / "box.stl")
    (tmp_path / "scene.toml").write_text(SCENE)
    return tmp_path / "scene.toml"


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    """A socket that accepts connections (the kernel's backlog) and never answers."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen(8)
        yield sock


@pytest.fixture
def http_server() -> Iterator[int]:
    class Page(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 (the standard library's name)
            self.send_response(200)
            self.end_headers()
            self.wfile.write(b"<html>dashboard</html>")

        def log_message(self, *args) -> None:
            pass

    class Quiet(ThreadingHTTPServer):
        def handle_error(self, request, client_address) -> None:
            pass  # the probe hangs up without reading the page: not the test's stderr

    server = Quiet(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()


@pytest.fixture
def chatter() -> Iterator[int]:
    """A server that greets every connection with bytes that are not Dask's."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)
    stop = threading.Event()

    def serve() -> None:
        sock.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = sock.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"\xff" * 64)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield sock.getsockname()[1]
    stop.set()
    thread.join()
    sock.close()


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _wedge(scene: Path, address: str, timeout: str = "2") -> str:
    with deadline(15.0), unchanged(scene.parent, [scene]):
        outcome = run_blastvox("wedge", scene, "--vary", "seed=0,1", "--scheduler", address,
                               "--connect-timeout", timeout, "-o", scene.parent / "w")
    line = assert_clean_failure(outcome, [f"--scheduler {address}"], seconds=float(timeout) + 3)
    assert "out of memory" not in line
    return line


def test_nothing_listening_is_refused_at_once(scene: Path) -> None:
    line = _wedge(scene, f"tcp://127.0.0.1:{_free_port()}")
    assert "connection refused" in line


def test_a_listener_that_never_answers_ends_within_the_timeout(scene, listener) -> None:
    port = listener.getsockname()[1]
    line = _wedge(scene, f"tcp://127.0.0.1:{port}")
    assert "nothing answers within 2 s" in line and "--connect-timeout" in line


@pytest.mark.parametrize("form", ["tcp://127.0.0.1:{port}", "127.0.0.1:{port}"])
def test_an_http_server_is_named_not_out_of_memory(scene, http_server, form) -> None:
    line = _wedge(scene, form.format(port=http_server))
    assert "an HTTP server answers there" in line and "8786" in line


def test_an_http_address_is_the_dashboard_s(scene, http_server) -> None:
    line = _wedge(scene, f"http://127.0.0.1:{http_server}")
    assert "web page" in line and "tcp://host:8786" in line


def test_a_server_speaking_something_else(scene, chatter) -> None:
    line = _wedge(scene, f"tcp://127.0.0.1:{chatter}")
    assert "not in Dask's protocol" in line


@pytest.mark.parametrize("address, words", [
    ("tcp://no-such-host.invalid:8786", ["cannot resolve host"]),
    ("tcp://127.0.0.1:99999", ["not a TCP port"]),
    ("bogus://x", ["unknown address scheme"]),
])
def test_addresses_that_name_nothing(scene, address, words) -> None:
    line = _wedge(scene, address)
    for word in words:
        assert word in line, line
