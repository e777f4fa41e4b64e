"""``--live [HOST:]PORT``: the address of the live server, parsed with one-line errors.

The Foxglove WebSocket listens on ``PORT`` and the page on ``PORT + 1``, so ``PORT`` is
in 1-65534. ``HOST`` may be a name, an IPv4 address or a bracketed IPv6 address
(``[::1]:8765``); without it the server listens on 127.0.0.1 only.
"""

from __future__ import annotations

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: What ``--live`` without a value means.
DEFAULT_ADDRESS = f"{DEFAULT_HOST}:{DEFAULT_PORT}"


class LiveError(ValueError):
    """The live server cannot start (a bad address, a port in use); the message says which."""


def parse_address(text: str, option: str = "--live") -> tuple[str, int]:
    """``(host, port)`` from ``PORT``, ``:PORT``, ``HOST:PORT`` or ``[IPv6]:PORT``."""
    s = text.strip()
    where = f"{option} {text!r}"
    if not s:
        raise LiveError(f"{where}: give [HOST:]PORT, e.g. {DEFAULT_ADDRESS} or 9000")
    if s.startswith("["):
        end = s.find("]")
        if end < 0 or s[end + 1:end + 2] != ":":
            raise LiveError(f"{where}: an IPv6 address is written [ADDRESS]:PORT, e.g. [::1]:8765")
        host, port_text = s[1:end], s[end + 2:]
    elif ":" in s:
        host, port_text = s.rsplit(":", 1)
        if ":" in host:
            raise LiveError(f"{where}: an IPv6 address is written [ADDRESS]:PORT, e.g. [::1]:8765")
        host = host or DEFAULT_HOST
    else:
        host, port_text = DEFAULT_HOST, s
    if not host or any(c.isspace() for c in host):
        raise LiveError(f"{where}: the host name is empty or holds a space")
    if not port_text.isdigit():
        raise LiveError(f"{where}: the port {port_text!r} is not a number (1-65534)")
    port = int(port_text)
    if not 1 <= port <= 65534:
        raise LiveError(f"{where}: the port {port} is out of range: 1-65534 (the page uses PORT + 1)")
    return host, port


def url_host(host: str) -> str:
    """``host`` as it appears in a URL (IPv6 in brackets)."""
    return f"[{host}]" if ":" in host else host
