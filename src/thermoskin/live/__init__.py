"""See the skin live: the loop's topics over the Foxglove WebSocket protocol, and a page.

``thermoskin run --live [HOST:]PORT`` and ``thermoskin replay RUN.mcap --live [HOST:]PORT``
start a :class:`LiveServer` in the parent process: channels with the recording's topics
and JSON schemas (``ws://HOST:PORT``, for Foxglove or Lichtblick) and a self-contained
page (``http://HOST:PORT+1/``). See ``docs/live.md``.
"""

from thermoskin.live.address import DEFAULT_ADDRESS, LiveError, parse_address, url_host
from thermoskin.live.messages import EVENT_TOPICS, SIGNAL_TOPICS, Decimator, RowMessages
from thermoskin.live.replay import play
from thermoskin.live.server import Fanout, LiveServer, page_html

__all__ = ["DEFAULT_ADDRESS", "EVENT_TOPICS", "SIGNAL_TOPICS", "Decimator", "Fanout", "LiveError",
           "LiveServer", "RowMessages", "page_html", "parse_address", "play", "url_host"]
