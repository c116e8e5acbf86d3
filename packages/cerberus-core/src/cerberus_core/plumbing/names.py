"""Names from outside (file names, subject names, a model registry's text) made safe to show and to use.

* :func:`printable` — for a terminal or a one-line message: control characters (ANSI escapes, newlines,
  carriage returns) and undecodable bytes of a file name are shown as ``\\xNN`` escapes, never sent raw;
* :func:`did_you_mean` — the hint after an unknown name (`` (did you mean 'x'?)``), if a known one is close;
* :func:`safe_stem` — for an output file name: valid UTF-8, no control or path characters, no leading
  dot, and short enough that every name derived from it stays within the file system's limit.

HTML and Markdown escaping live where those are written (:mod:`cerberus_core.eval.viewer`,
:mod:`cerberus_core.eval.report`).
"""
from __future__ import annotations

import hashlib
import os
import unicodedata
from collections.abc import Iterable

#: Longest output stem in UTF-8 bytes: the longest suffix a command adds (``_reconstruction.png``,
#: 19 bytes), a de-duplicating counter and the atomic writer's temporary name (14 bytes) stay within
#: the usual 255-byte file name limit.
MAX_STEM_BYTES = 200


def _unsafe(ch: str) -> bool:
    """Control, format (bidi overrides), surrogate and line/paragraph separator characters."""
    return unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Zl", "Zp")


def printable(text: object) -> str:
    """``text`` with every control character and undecodable byte escaped (``\\x1b``, ``\\n``,
    ``\\udcff`` → ``\\xff``): what a file name or registry string may be printed as."""
    out = []
    for ch in str(text):
        if not _unsafe(ch):
            out.append(ch)
        elif 0xDC80 <= ord(ch) <= 0xDCFF:  # a byte of a non-UTF-8 file name (surrogateescape)
            out.append(f"\\x{ord(ch) - 0xDC00:02x}")
        else:
            out.append(ascii(ch)[1:-1])
    return "".join(out)


def safe_stem(stem: str, max_bytes: int = MAX_STEM_BYTES) -> str:
    """An output file name stem made from an input's stem.

    Bytes that are not UTF-8 become ``_``, as do control characters, path separators and a leading
    dot; an empty result is ``image``. A stem longer than ``max_bytes`` UTF-8 bytes is cut and gets
    ``-`` and 8 hex digits of the original's SHA-1, so two long names that differ only at the end
    stay distinct.
    """
    raw = os.fsencode(stem) if isinstance(stem, str) else bytes(stem)
    text = raw.decode("utf-8", "replace")
    text = "".join("_" if (_unsafe(ch) or ch in "/\\\ufffd") else ch for ch in text).lstrip(".") or "image"
    encoded = text.encode()
    if len(encoded) <= max_bytes:
        return text
    digest = hashlib.sha1(raw).hexdigest()[:8]
    cut = encoded[: max_bytes - 9].decode("utf-8", "ignore")  # never half a character
    return f"{cut}-{digest}"


__all__ = ["MAX_STEM_BYTES", "did_you_mean", "printable", "safe_stem"]


def did_you_mean(name: object, known: Iterable[object]) -> str:
    """`` (did you mean 'warp'?)``, to follow an unknown ``name`` in a message: the known name closest to it (case
    ignored first, then :func:`difflib.get_close_matches`), or ``""`` when none is close (or it is ``name`` itself)."""
    import difflib

    name = str(name)
    lowered = {str(k).lower(): str(k) for k in known}
    match = lowered.get(name.lower())
    if match is None:
        close = difflib.get_close_matches(name.lower(), list(lowered), n=1, cutoff=0.6)
        match = lowered[close[0]] if close else None
    return f" (did you mean {match!r}?)" if match is not None and match != name else ""
