"""See the skin live: the loop's topics over the Foxglove WebSocket protocol, and a page.

``thermoskin run --live [HOST:]PORT`` and ``thermoskin replay RUN.mcap --live [HOST:]PORT``
start a :class:`LiveServer` in the parent process: channels with the recording's topics
and JSON schemas (``ws://HOST:PORT``, for Foxglove or Lichtblick) and a self-contained
page (``http://HOST:PORT+1/``). See ``docs/live.md``.

The names below are imported on first use, so that ``thermoskin.live.address`` (which the
command line reads at start) does not load ``foxglove-sdk``.
"""

from __future__ import annotations

import importlib
from typing import Any

_WHERE = {
    "DEFAULT_ADDRESS": "address", "LiveError": "address", "parse_address": "address", "url_host": "address",
    "EVENT_TOPICS": "messages", "SIGNAL_TOPICS": "messages", "Decimator": "messages",
    "RowMessages": "messages", "play": "replay", "Fanout": "server", "LiveServer": "server",
    "page_html": "server",
}
__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'thermoskin.live' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"thermoskin.live.{module}"), name)
    globals()[name] = value
    return value
