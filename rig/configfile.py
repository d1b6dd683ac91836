"""YAML configuration files validated by pydantic, with one clear message on any error.

Campaign files and rig files share this: the message names the file, every bad
key (dotted path), its value and what is allowed; unknown keys list the keys
allowed at that place. YAML is read with `safe_load` only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)


class ConfigFileError(ValueError):
    """A configuration file that cannot be used; the message says where and why."""


def _describe_loc(loc: tuple, tags: Mapping[str, type]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in tags:          # discriminated-union tags add nothing for a user
            continue
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


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
    lines: list[str] = []
    for e in err.errors():
        key = _describe_loc(e["loc"], tags)
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(root, e["loc"], tags)
            msg = f"unknown key '{key}'" + (f"; allowed here: {', '.join(allowed)}" if allowed else "")
        else:
            reason = e["msg"].removeprefix("Value error, ")
            msg = f"key '{key}': value {e.get('input')!r} is not allowed: {reason}"
        if msg not in lines:
            lines.append(msg)
    return f"{source}: invalid {what}:\n  " + "\n  ".join(lines)


def parse_model(data: Any, model: type[M], *, source: str | Path, what: str,
                error: type[ConfigFileError] = ConfigFileError, tags: Mapping[str, type] = {}) -> M:
    if not isinstance(data, dict):
        raise error(f"{source}: a {what} must be a YAML mapping of keys, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise error(format_validation_error(source, what, model, err, tags)) from None


def read_yaml(path: str | Path, what: str, error: type[ConfigFileError] = ConfigFileError) -> Any:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: {what} file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read {what} file: {exc}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise error(f"{path}: not valid YAML{where}: {problem}") from None
