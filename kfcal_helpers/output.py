"""What the command line writes, shared by every sub-command: strict JSON, and the registry of
files being written
(:data:`kfcal_helpers.process.PARTIAL_FILES`, removed by the command line's signal handler), and a
check that a text can be printed."""

from __future__ import annotations

import json
import math

from .process import PARTIAL_FILES
from .validation import checked, optional, require_bool, require_mapping, require_path, require_stream, require_text

__all__ = ["dumps_json", "PARTIAL_FILES", "require_printable", "path_text", "print_summary"]


def _strict(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def dumps_json(obj) -> str:
    """``obj`` as strict JSON (``allow_nan=False``): a non-finite float (NaN, infinity) becomes null."""
    try:
        return json.dumps(_strict(obj), allow_nan=False)
    except TypeError as exc:  # an object JSON has no form for (an array, a set, ...)
        raise ValueError(f"obj must be made of dicts, lists, str, numbers, True, False and None ({exc})") from None


@checked(name=require_text, text=require_text, stream=optional(require_stream))
def require_printable(name: str, text: str, stream=None) -> str:
    """``text`` if ``stream`` (default ``sys.stdout``) can write it in its encoding and error setting,
    else ValueError naming ``name``; a command checks the lines it will print before it writes files."""
    import sys

    stream = sys.stdout if stream is None else stream
    encoding = getattr(stream, "encoding", None)
    if stream is None or not encoding:
        return text
    try:
        text.encode(encoding, getattr(stream, "errors", None) or "strict")
    except (UnicodeError, LookupError) as exc:
        raise ValueError(f"{name}: {text!r} cannot be printed in the output's encoding {encoding} ({exc.reason}); "
                         "set PYTHONIOENCODING=utf-8") from None
    return text


@checked(path=require_path, stream=optional(require_stream))
def path_text(path, stream=None) -> str:
    """``path`` as text to print on ``stream`` (default ``sys.stdout``): each character the stream's
    encoding lacks as a backslash escape (``\\xe9``, ``\\u03c3``), never a look-alike, so the printed
    path is unambiguous in any encoding; a file name's undecodable bytes (surrogate escapes) are kept,
    to be written back as those bytes."""
    import sys

    text = str(path)
    stream = sys.stdout if stream is None else stream
    encoding = getattr(stream, "encoding", None) or "utf-8"
    out = []
    for ch in text:
        if 0xDC80 <= ord(ch) <= 0xDCFF:
            out.append(ch)
            continue
        try:
            ch.encode(encoding)
            out.append(ch)
        except UnicodeEncodeError:
            out.append(ch.encode("ascii", "backslashreplace").decode("ascii"))
        except LookupError:
            return text
    return "".join(out)


@checked(out=require_mapping, as_json=require_bool, tail=optional(require_text))
def print_summary(out: dict, as_json: bool = False, tail: str | None = None) -> None:
    """Print a command's summary ``out`` (key -> number, text, bool or list of numbers): one strict JSON
    object, or one ``key  value`` line per entry (numbers to 4 significant digits, booleans yes/no, texts
    with :func:`path_text`), then ``tail`` (a table) when given."""
    if as_json:
        print(dumps_json(out))
        return
    width = max(len(k) for k in out)
    for key, value in out.items():
        if isinstance(value, bool):
            value = "yes" if value else "no"
        elif isinstance(value, float):
            value = f"{value:.4g}"
        elif isinstance(value, list):
            value = "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
        elif isinstance(value, str):
            value = path_text(value)
        print(f"{key:<{width}}  {value}")
    if tail:
        print(tail)
