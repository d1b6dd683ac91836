"""Reading JSON from a file anyone may have edited (dataset.json, events.jsonl, a fit, road.json): every way
the parse can fail is one `JsonFileError` naming the file and, where it is known, the line.

`json.loads` fails in more ways than `JSONDecodeError`: a number of more than Python's integer digit limit
(4300 by default) is a plain ValueError, nesting deeper than the recursion limit a RecursionError, bytes that
are not UTF-8 a UnicodeDecodeError. A reader that catches only the first gives a traceback for the others.
What the parsed value must hold is each reader's own check; this module only turns text into a value.
"""

from __future__ import annotations

import json
import os
import re
import sys
from typing import Any


class JsonFileError(ValueError):
    """A JSON file (or one line of a JSON-lines file) cannot be parsed; the message names where and why."""

    def __init__(self, source: str | os.PathLike, reason: str, line: int | None = None):
        self.source, self.reason, self.line = str(source), reason, line
        super().__init__(f"{source}{'' if line is None else f':{line}'}: {reason}")


_KINDS = {dict: "object", list: "array", str: "string", int: "number", float: "number", bool: "boolean"}


def json_kind(value: Any) -> str:
    """What a parsed JSON value is, in JSON's words ("an array"), for messages about a wrong type."""
    return "a JSON " + _KINDS.get(type(value), "value") if value is not None else "null"


def _line_of(text: str, offset: int, first_line: int) -> int:
    return first_line + text.count("\n", 0, offset)


def _one_line(text: str, first_line: int) -> int | None:
    """The line of an error without a position: known only when the text is one line."""
    return first_line if "\n" not in text.strip() else None


#: A `\\uD800`–`\\uDFFF` escape: valid JSON, but alone (not a pair) it is no Unicode character, and writing the
#: string out (a report, a figure's title) fails far from the file.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F][0-9a-fA-F]{2}")


def _has_lone_surrogate(value: Any) -> bool:
    if isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            return True
        return False
    if isinstance(value, dict):
        return any(_has_lone_surrogate(k) or _has_lone_surrogate(v) for k, v in value.items())
    if isinstance(value, list):
        return any(_has_lone_surrogate(v) for v in value)
    return False


def parse_json(text: str, source: str | os.PathLike, *, first_line: int = 1) -> Any:
    """The value of the JSON `text` read from `source` (its first line numbered `first_line`); JsonFileError
    for anything that is not JSON Python can hold, or holds a string that is not Unicode text."""
    value = _parse(text, source, first_line)
    escape = _SURROGATE_ESCAPE.search(text)
    try:
        lone = escape is not None and _has_lone_surrogate(value)
    except RecursionError:
        raise JsonFileError(source, "JSON nested too deeply", _one_line(text, first_line)) from None
    if escape and lone:
        raise JsonFileError(source, f"a string with a lone UTF-16 surrogate ({escape.group()}…), not Unicode text",
                            _line_of(text, escape.start(), first_line))
    return value


def _parse(text: str, source: str | os.PathLike, first_line: int) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise JsonFileError(source, f"not valid JSON ({exc.msg})", first_line - 1 + exc.lineno) from None
    except RecursionError:
        raise JsonFileError(source, "JSON nested too deeply", _one_line(text, first_line)) from None
    except ValueError:              # int(): more digits than sys.get_int_max_str_digits()
        limit = sys.get_int_max_str_digits()
        long = re.search(rf"\d{{{limit + 1},}}", text) if limit else None
        line = _line_of(text, long.start(), first_line) if long else _one_line(text, first_line)
        raise JsonFileError(source, f"a number of more than {limit} digits", line) from None


def decode_utf8(data: bytes, source: str | os.PathLike) -> str:
    """`data` as UTF-8 text; JsonFileError naming the line of the first byte that is not."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise JsonFileError(source, f"not UTF-8 text (byte {exc.start})", data.count(b"\n", 0, exc.start) + 1) \
            from None


def read_json(path: str | os.PathLike) -> Any:
    """The value of the JSON file `path`; JsonFileError naming it for a file that cannot be read or parsed."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise JsonFileError(path, f"cannot read it ({exc.strerror or exc})") from None
    return parse_json(decode_utf8(data, path), path)
