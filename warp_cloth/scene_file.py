"""Scene files: TOML in, a checked ``Scene`` out, or a ``SceneError`` naming file, key and expectation.

The file's tables and keys are the dataclass fields of ``warp_cloth.scene`` (a field may name its TOML
key in its metadata, as ``Scene.cloths`` does with ``[[cloth]]``), so the schema lives in one place.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from .errors import SceneError
from .model import select_pins
from .scene import Scene

_BUILTIN_PACKAGE = "warp_cloth.scenes"


def builtin_scene_names() -> list[str]:
    """The built-in scenes, by name (the file stem)."""
    folder = resources.files(_BUILTIN_PACKAGE)
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def resolve_scene_path(name_or_path: str | Path) -> Path:
    """A path to an existing scene file, or a built-in's file when given a built-in's name."""
    text = str(name_or_path)
    if text in builtin_scene_names():
        return Path(str(resources.files(_BUILTIN_PACKAGE).joinpath(f"{text}.toml")))
    path = Path(text)
    if not path.is_file():
        known = ", ".join(builtin_scene_names())
        raise SceneError("", f"an existing scene file (no such file) or a built-in scene name ({known})",
                         has_got=False, source=text)
    return path


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a built-in scene by name, or a scene file by path."""
    path = resolve_scene_path(name_or_path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("", f"valid TOML ({exc})", has_got=False, source=str(path)) from None
    except OSError as exc:
        raise SceneError("", f"a readable file ({exc.strerror})", has_got=False, source=str(path)) from None
    if "name" not in data:
        data["name"] = path.stem
    try:
        return scene_from_dict(data)
    except SceneError as exc:
        raise exc.in_file(str(path)) from None


def scene_from_dict(data: dict[str, Any]) -> Scene:
    """A ``Scene`` from plain data as TOML gives it, with its pins resolved; errors name the key path."""
    scene = _convert(data, Scene, "")
    select_pins(scene)
    return scene


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _convert(value: Any, hint: Any, path: str) -> Any:
    origin = get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return _to_dataclass(value, hint, path)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in get_args(hint) if a is not type(None)]
        if len(options) == 1:
            return _convert(value, options[0], path)
        raise TypeError(f"unsupported union {hint}")
    if origin is Literal:
        choices = get_args(hint)
        if value not in choices:
            raise SceneError(path, "one of " + ", ".join(repr(c) for c in choices), value)
        return value
    if origin is tuple:
        args = get_args(hint)
        if not isinstance(value, list):
            raise SceneError(path, _describe(hint), value)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(item, args[0], f"{path}[{k}]") for k, item in enumerate(value))
        if len(value) != len(args):
            raise SceneError(path, _describe(hint), value)
        return tuple(_convert(item, arg, f"{path}[{k}]") for k, (item, arg) in enumerate(zip(value, args)))
    if hint is bool:
        if not isinstance(value, bool):
            raise SceneError(path, "true or false", value)
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(path, "a whole number", value)
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(path, "a number", value)
        if not math.isfinite(value):
            raise SceneError(path, "a finite number", value)
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(path, "a string", value)
        return value
    raise TypeError(f"unsupported type {hint} at {path}")


def _toml_key(f: dataclasses.Field) -> str:
    return f.metadata.get("toml", f.name)


def _to_dataclass(value: Any, cls: type, path: str) -> Any:
    if not isinstance(value, dict):
        raise SceneError(path, f"a table of {cls.__name__} settings", value)
    hints = typing.get_type_hints(cls)
    fields = {_toml_key(f): f for f in dataclasses.fields(cls)}
    for key in value:
        if key not in fields:
            raise SceneError(_join(path, key), "a known key (one of " + ", ".join(sorted(fields)) + ")",
                             has_got=False)
    kwargs = {f.name: _convert(value[key], hints[f.name], _join(path, key))
              for key, f in fields.items() if key in value}
    try:
        return cls(**kwargs)
    except SceneError as exc:
        raise (exc.within(path) if path else exc) from None


def _describe(hint: Any) -> str:
    args = get_args(hint)
    if len(args) == 2 and args[1] is Ellipsis:
        return f"a list of {_describe(args[0])}" if not dataclasses.is_dataclass(args[0]) else "an array of tables"
    if args and all(a is float for a in args):
        return f"a list of {len(args)} numbers"
    if args and all(a is int for a in args):
        return f"a list of {len(args)} whole numbers"
    if hint is int:
        return "whole numbers"
    if hint is float:
        return "numbers"
    if hint is str:
        return "strings"
    if get_origin(hint) is Literal:
        return "names (" + ", ".join(repr(c) for c in get_args(hint)) + ")"
    return str(hint)
