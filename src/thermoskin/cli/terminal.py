"""Output that a terminal of any locale can take: ASCII where its encoding cannot say more.

Under an ASCII-only locale (``LC_ALL=C`` with Python's locale coercion and UTF-8 mode off, as
some service managers and containers start programs) ``sys.stdout`` and ``sys.stderr`` encode
ASCII strictly, and the first "µs" or "°C" of a summary raised ``UnicodeEncodeError`` after a
run's data was written: a traceback and exit 1 where a fault's exit code is 3.
:func:`degrade_to_ascii` gives both streams an error handler that writes each character they
cannot encode in ASCII words (``µ`` as ``u``, ``°`` as ``deg``, ``±`` as ``+-``, ``→`` as
``->``; a letter with an accent as the letter; anything else as ``?``), so that the output
reads the same with fewer characters. A terminal that encodes them is left as it is.
"""

from __future__ import annotations

import codecs
import contextlib
import sys
import unicodedata
from typing import Any

#: The characters the command line prints that have no ASCII form of their own.
ASCII_WORDS = {
    "µ": "u", "μ": "u", "°": "deg", "±": "+-", "→": "->", "←": "<-", "↔": "<->", "×": "x", "·": ".",
    "≈": "~", "≤": "<=", "≥": ">=", "≠": "!=", "–": "-", "—": "--", "‘": "'", "’": "'", "“": '"',
    "”": '"', "…": "...", "²": "^2", "³": "^3", "½": "1/2", "Δ": "d", "δ": "d", "Ω": "Ohm",
    "σ": "sd", "√": "sqrt", "∞": "inf", "•": "*", "━": "-", "─": "-", "│": "|", "✓": "ok", "✗": "x",
}

HANDLER = "thermoskin-ascii"
#: Longest error message, characters: what an input put in it (a name, a value) is cut.
MAX_MESSAGE = 400


def one_line(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` as one line of at most ``limit`` characters: blanks and line breaks as one space,
    a longer text cut in its middle (its start says what and where, its end often what to do)."""
    if len(text) > 64 * limit:  # a huge message: only its two ends are looked at
        text = text[: 32 * limit] + " " + text[-32 * limit:]
    msg = " ".join(text.split())
    if len(msg) <= limit:
        return msg
    tail = limit // 4
    return msg[: limit - tail - 5] + " ... " + msg[-tail:]


def to_ascii(text: str) -> str:
    """``text`` in ASCII: :data:`ASCII_WORDS`, accents dropped, anything else ``?``."""
    out = []
    for ch in text:
        if ch.isascii():
            out.append(ch)
        elif ch in ASCII_WORDS:
            out.append(ASCII_WORDS[ch])
        else:
            base = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode()
            out.append(base or "?")
    return "".join(out)


def _handler(exc: UnicodeError) -> tuple[str, int]:
    if not isinstance(exc, UnicodeEncodeError):
        raise exc
    return to_ascii(exc.object[exc.start:exc.end]), exc.end


codecs.register_error(HANDLER, _handler)


def _needs_ascii(stream: Any) -> bool:
    enc = getattr(stream, "encoding", None)
    if not enc:
        return False
    try:
        "µ°±→".encode(enc)
    except (UnicodeEncodeError, LookupError):
        return True
    return False


def degrade_to_ascii() -> None:
    """Give ``sys.stdout`` and ``sys.stderr`` the ASCII words (:func:`to_ascii`) where their
    encoding cannot encode what the commands print (module doc); nothing otherwise."""
    for stream in (sys.stdout, sys.stderr):
        if stream is not None and _needs_ascii(stream) and hasattr(stream, "reconfigure"):
            with contextlib.suppress(ValueError, OSError, AttributeError):
                stream.reconfigure(errors=HANDLER)
