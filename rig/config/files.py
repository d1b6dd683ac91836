"""YAML configuration files validated by pydantic, with one clear message on any error.

Campaign files and rig files share this: the message names the file, every bad
key (dotted path), its value and what is allowed; unknown keys list the keys
allowed at that place.

Reading is bounded, because a config file is input from anyone: YAML is read
with a safe loader only (no tags that run code), at most `MAX_FILE_BYTES`,
nested at most `MAX_DEPTH` deep, and standing for at most `MAX_NODES` values
with its aliases expanded. Aliases are allowed (a rig file may share one axis
block between axes) but cannot blow up: a "billion laughs" file of a few hundred
bytes is refused before anything walks its expansion. Keys given twice in one
mapping are refused with their line, since YAML would silently keep the last.
Messages show a value only up to `VALUE_CHARS` characters and never print a
whole parent mapping: a missing key is named by its path alone.
"""

from __future__ import annotations

import reprlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)

#: Largest file read (bytes). Shipped campaigns and rig files are a few kB; a megabyte holds some
#: 60,000 explicit views written out one per line.
MAX_FILE_BYTES = 1 << 20
#: Deepest nesting of mappings and lists (the schemas need 6).
MAX_DEPTH = 32
#: Most values (scalars, lists, mappings) a file may stand for with its aliases expanded.
MAX_NODES = 500_000
#: Longest rendering of a value or key in a message.
VALUE_CHARS = 80
#: Problems listed in one message; the rest are counted.
MAX_PROBLEMS = 20

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist = 2, 4, 6
_REPR.maxstring = _REPR.maxother = _REPR.maxlong = VALUE_CHARS


class ConfigFileError(ValueError):
    """A configuration file that cannot be used; the message says where and why."""


def clip(text: str, limit: int = VALUE_CHARS) -> str:
    """`text` cut to at most `limit` characters, the cut marked with an ellipsis."""
    return text if len(text) <= limit else text[:limit - 1] + "…"


def short(value: Any, limit: int = VALUE_CHARS) -> str:
    """repr of `value` for a message, at most `limit` characters whatever its size."""
    return clip(repr(value) if isinstance(value, str) else _REPR.repr(value), limit)


def printable(text: str) -> str:
    """A pydantic validator for names and paths, which end up in folders, manifests and terminals:
    no control characters."""
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise ValueError("control characters (tab, newline, NUL, …) are not allowed")
    return text


class _Refused(yaml.YAMLError):
    """A file the bounded loader will not read further; carries the line where it stopped."""

    def __init__(self, problem: str, mark: yaml.Mark | None):
        super().__init__(problem)
        self.problem, self.problem_mark = problem, mark


class _BoundedSafeLoader(yaml.SafeLoader):
    """SafeLoader that refuses deep nesting, alias expansion beyond MAX_NODES and duplicate keys."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _Refused(f"nested deeper than {MAX_DEPTH} levels", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_document(self, node):
        _check_expansion(node)
        return super().construct_document(node)

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node)
                line = key_node.start_mark.line + 1
                if key in seen:
                    raise _Refused(f"key {short(key)} given twice (lines {seen[key]} and {line})",
                                   key_node.start_mark)
                seen[key] = line
        return super().construct_mapping(node, deep=deep)


def _check_expansion(root: yaml.Node) -> None:
    """Refuse a document whose aliases expand beyond MAX_NODES values or MAX_DEPTH levels, or refer to
    themselves. Sizes are memoised per node, so this costs one visit per node as written, not expanded."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()

    def size(node: yaml.Node, depth: int) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in on_path:
            raise _Refused("an alias refers to the mapping or list that contains it", node.start_mark)
        if depth > MAX_DEPTH:
            raise _Refused(f"aliases nest values deeper than {MAX_DEPTH} levels", node.start_mark)
        on_path.add(key)
        children = ([n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode)
                    else node.value if isinstance(node, yaml.SequenceNode) else [])
        total = 1
        for child in children:
            total += size(child, depth + 1)
            if total > MAX_NODES:
                raise _Refused(f"stands for more than {MAX_NODES} values with its aliases expanded",
                               node.start_mark)
        on_path.discard(key)
        sizes[key] = total
        return total

    size(root, 1)


def _key_path(loc: tuple, tags: Mapping[str, type]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in tags:          # discriminated-union tags add nothing for a user
            continue
        else:
            out += ("." if out else "") + str(part)
    return clip(out or "(top level)")


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    candidates = [annotation, *getattr(annotation, "__args__", ())]
    for arg in list(candidates):
        candidates.extend(getattr(arg, "__args__", ()))
    return [c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)]


def _allowed_keys(root: type[BaseModel], loc: tuple, tags: Mapping[str, type]) -> list[str] | None:
    """Field names of the model an unknown key was found in."""
    model: Any = root
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if part in tags:
            model = tags[part]
            continue
        field = getattr(model, "model_fields", {}).get(part)
        models = _models_in(field.annotation) if field is not None else []
        if not models:
            return None
        model = models[0]
    return list(getattr(model, "model_fields", {}))


def format_validation_error(source: str | Path, what: str, root: type[BaseModel], err: ValidationError,
                            tags: Mapping[str, type] = {}) -> str:
    """One line per problem: the key path, the value (shortened; never a whole mapping) and the rule."""
    lines: list[str] = []
    for e in err.errors():
        key = _key_path(e["loc"], tags)
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(root, e["loc"], tags)
            msg = f"unknown key '{key}'" + (f"; allowed here: {', '.join(allowed)}" if allowed else "")
        elif e["type"] == "missing":
            msg = f"missing key '{key}'"
        else:
            reason = clip(e["msg"].removeprefix("Value error, "), 4 * VALUE_CHARS)
            value = e.get("input")
            shown = "" if isinstance(value, Mapping) else f"value {short(value)} "
            msg = f"key '{key}': {shown}is not allowed: {reason}"
        if msg not in lines:
            lines.append(msg)
    more = len(lines) - MAX_PROBLEMS
    listed = lines[:MAX_PROBLEMS] + ([f"… and {more} more"] if more > 0 else [])
    return f"{source}: invalid {what}:\n  " + "\n  ".join(listed)


def parse_model(data: Any, model: type[M], *, source: str | Path, what: str,
                error: type[ConfigFileError] = ConfigFileError, tags: Mapping[str, type] = {}) -> M:
    if not isinstance(data, dict):
        raise error(f"{source}: a {what} must be a YAML mapping of keys, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise error(format_validation_error(source, what, model, err, tags)) from None


def read_yaml(path: str | Path, what: str, error: type[ConfigFileError] = ConfigFileError) -> Any:
    """The file's one YAML document, read within the bounds of the module docstring."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
        if len(raw) > MAX_FILE_BYTES:
            raise error(f"{path}: {what} file larger than {MAX_FILE_BYTES // 1024} kB; is it the right file?")
        text = raw.decode("utf-8")
    except FileNotFoundError:
        raise error(f"{path}: {what} file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read {what} file: {exc}") from None
    try:
        return yaml.load(text, Loader=_BoundedSafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        kind = "refused" if isinstance(exc, _Refused) else "not valid YAML"
        raise error(f"{path}: {kind}{where}: {clip(problem, 4 * VALUE_CHARS)}") from None
    except (ValueError, OverflowError, RecursionError) as exc:   # e.g. `!!float x`, an int of 5000 digits
        raise error(f"{path}: not valid YAML: {clip(str(exc), 4 * VALUE_CHARS)}") from None
