"""Is a Dask scheduler at ``--scheduler``? Asked before the Dask client connects (issue 36).

Dask's client waits past its timeout on a listener that never answers (a 3 s
``--connect-timeout`` hung 60 s) and reads an HTTP server's reply as a frame
length (an allocation of exabytes: "out of memory"). So :func:`probe` opens the
TCP connection itself and waits, within the timeout, for the first bytes a
scheduler sends on every connection (its handshake, a frame of a few hundred
bytes); what it finds is one :class:`~blastvox.errors.WedgeError` line naming
the address and the cause: nothing listens (refused), no host by that name, no
route, no answer in time, an HTTP server (the dashboard's port, 8787, for the
scheduler's, 8786), or bytes that are not Dask's.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time

from blastvox.errors import WedgeError

#: The longest handshake frame a scheduler sends (bytes); larger is not Dask.
MAX_HANDSHAKE_BYTES = 1 << 20
#: Share of the timeout spent waiting for the handshake before asking in HTTP.
_HANDSHAKE_SHARE = 0.7


def probe(address: str, timeout_s: float) -> float:
    """Check that a Dask scheduler answers at ``address`` (``tcp://host:port``,
    ``host:port``; a TLS, websocket or other address is left to Dask); returns the
    seconds left of ``timeout_s``. Raises WedgeError naming the cause."""
    from distributed.comm.addressing import parse_address, parse_host_port

    started = time.monotonic()
    if address.lower().startswith(("http://", "https://")):
        raise _error(address, "an http:// address is a web page (the dashboard, port "
                     "8787); the scheduler's is tcp://host:8786")
    try:
        scheme, location = parse_address(address)
        if scheme != "tcp":
            return timeout_s
        host, port = parse_host_port(location, 8786)
    except (ValueError, TypeError) as exc:
        raise _error(address, f"not a scheduler address ({exc})") from None
    if not 0 < port < 65536:
        raise _error(address, f"{port} is not a TCP port (1 to 65535)")

    def left() -> float:
        return max(0.05, timeout_s - (time.monotonic() - started))

    try:
        conn = socket.create_connection((host, port), timeout=left())
    except socket.gaierror as exc:
        raise _error(address, f"cannot resolve host {host!r} ({exc.strerror})") from None
    except ConnectionRefusedError:
        raise _error(address, "connection refused: nothing listens on that port (is the "
                     "scheduler running, on that port?)") from None
    except TimeoutError:
        raise _error(address, f"no answer to the connection within {timeout_s:g} s (a "
                     "firewall, or no such host; --connect-timeout)") from None
    except OSError as exc:
        raise _error(address, f"cannot connect ({exc.strerror or exc})") from None
    with conn:
        first = _receive(conn, 8, left() * _HANDSHAKE_SHARE)
        if first is None:  # silent: an HTTP server waits for a request
            with contextlib.suppress(OSError):
                conn.sendall(b"GET / HTTP/1.0\r\nHost: " + host.encode("ascii", "replace")
                             + b"\r\n\r\n")
            reply = _receive(conn, 5, left()) or b""
            if reply.startswith(b"HTTP/"):
                raise _error(address, _HTTP)
            raise _error(address, f"the connection is accepted but nothing answers within "
                         f"{timeout_s:g} s; not a Dask scheduler (--connect-timeout)")
        if first.startswith(b"HTTP/") or first[:1] == b"<":
            raise _error(address, _HTTP)
        if len(first) < 8:
            raise _error(address, "the connection is closed before the scheduler's "
                         "handshake; not a Dask scheduler, or it refuses this client")
        (size,) = struct.unpack("<Q", first)
        if not 0 < size <= MAX_HANDSHAKE_BYTES:
            raise _error(address, f"it answers, but not in Dask's protocol (first bytes "
                         f"{first!r}); not a Dask scheduler")
    return left()


_HTTP = ("an HTTP server answers there, not a Dask scheduler (the dashboard is on port "
         "8787, the scheduler usually on 8786: tcp://host:8786)")


def _error(address: str, cause: str) -> WedgeError:
    return WedgeError(f"--scheduler {address}: {cause}")


def _receive(conn: socket.socket, count: int, timeout: float) -> bytes | None:
    """Up to ``count`` bytes within ``timeout`` (fewer if the peer closes), or None if
    nothing came."""
    deadline = time.monotonic() + timeout
    data = b""
    while len(data) < count:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            break
        conn.settimeout(remaining)
        try:
            chunk = conn.recv(count - len(data))
        except TimeoutError:
            break
        except OSError:
            return data or b""
        if not chunk:
            return data
        data += chunk
    return data or None
