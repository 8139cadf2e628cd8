"""The value checks every scene dataclass runs on itself, from a file or from Python alike.

``check_fields`` checks each field against its type hint: numbers are real and finite in float32 (what
the device computes in), whole numbers fit in int32, choices are one of the ``Literal``'s, lists have
their length, nested settings are of their class. It stores each value in its plain form (a list
becomes a tuple, an int in a float field a float), so a scene built in Python holds what a file gives.
"""

from __future__ import annotations

import dataclasses
import functools
import numbers
import re
import types
import typing
from typing import Any, Literal, get_args, get_origin

import numpy as np

from .errors import SceneError

FLOAT32_MAX = float(np.finfo(np.float32).max)
FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # the smallest normal float32
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1

# A name becomes a file name (SCENE.usdc, CLOTH.0001.poly) and, for cloths and spheres, a USD prim name.
MAX_NAME_LENGTH = 100
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*")
# Names Windows keeps for devices, with any extension (CON.0001.poly is the console there).
_DEVICE_NAMES = {"con", "prn", "aux", "nul", *(f"com{k}" for k in range(1, 10)), *(f"lpt{k}" for k in range(1, 10))}


def toml_key(f: dataclasses.Field) -> str:
    """The key a field has in a scene file (``Scene.cloths`` is ``[[cloth]]``)."""
    return f.metadata.get("toml", f.name)


def check_fields(obj: Any) -> None:
    """Check every field of dataclass ``obj`` against its type hint, storing the plain form of each value."""
    hints = _type_hints(type(obj))
    for f in dataclasses.fields(obj):
        value = _checked(getattr(obj, f.name), hints[f.name], toml_key(f))
        object.__setattr__(obj, f.name, value)


@functools.cache
def _type_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def describe(hint: Any) -> str:
    """What a value of type ``hint`` looks like, in a scene file's terms."""
    origin = get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(describe(a) for a in get_args(hint) if a is not type(None))
    if dataclasses.is_dataclass(hint):
        return f"a table of {hint.__name__} settings"
    if origin is Literal:
        names = get_args(hint)
        return repr(names[0]) if len(names) == 1 else "one of " + ", ".join(repr(c) for c in names)
    if origin is tuple:
        args = get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return "an array of tables" if dataclasses.is_dataclass(args[0]) else f"a list of {_plural(args[0])}"
        return f"a list of {len(args)} {_plural(args[0])}" if len(set(args)) == 1 else f"a list of {len(args)} values"
    return {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}[hint]


def _plural(hint: Any) -> str:
    if get_origin(hint) is Literal:
        return "names (" + ", ".join(repr(c) for c in get_args(hint)) + ")"
    return {int: "whole numbers", float: "numbers", str: "strings"}.get(hint, str(hint))


def _checked(value: Any, hint: Any, key: str) -> Any:
    origin = get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in get_args(hint) if a is not type(None)]
        if value is None or len(options) == 1:
            return None if value is None else _checked(value, options[0], key)
        # several kinds (a whole number or a name): the value's own kind says which it must be
        chosen = next((o for o in options if get_origin(o) is Literal), None) if isinstance(value, str) else None
        if isinstance(value, (list, tuple)):  # one number or a list of them: the list's option
            chosen = next((o for o in options if get_origin(o) is tuple), None)
        if chosen is None:
            chosen = next((o for o in options if get_origin(o) is not Literal), options[0])
        try:
            return _checked(value, chosen, key)
        except SceneError:
            raise SceneError(key, describe(hint), value) from None
    if dataclasses.is_dataclass(hint):
        if not isinstance(value, hint):
            raise SceneError(key, describe(hint), value)
        return value
    if origin is Literal:
        if not isinstance(value, str) or value not in get_args(hint):
            raise SceneError(key, describe(hint), value)
        return value
    if origin is tuple:
        return _checked_tuple(value, hint, key)
    if hint is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise SceneError(key, describe(hint), value)
        return bool(value)
    if hint is int:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            raise SceneError(key, "a whole number", value)
        if not INT32_MIN <= int(value) <= INT32_MAX:
            raise SceneError(key, f"a whole number in [{INT32_MIN}, {INT32_MAX}] (int32)", value)
        return int(value)
    if hint is float:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise SceneError(key, "a number", value)
        value = float(value)
        if not abs(value) <= FLOAT32_MAX:  # also false for nan
            raise SceneError(key, f"a finite number (float32: magnitude at most {FLOAT32_MAX:.4g})", value)
        return value
    if hint is str:
        if not isinstance(value, str):
            raise SceneError(key, "a string", value)
        return value
    raise TypeError(f"unsupported type {hint} at {key}")


def _checked_tuple(value: Any, hint: Any, key: str) -> tuple:
    args = get_args(hint)
    if not isinstance(value, (tuple, list)):
        raise SceneError(key, describe(hint), value)
    if len(args) == 2 and args[1] is Ellipsis:
        args = (args[0],) * len(value)
    elif len(value) != len(args):
        raise SceneError(key, describe(hint), value)
    return tuple(_checked(item, arg, f"{key}[{k}]") for k, (item, arg) in enumerate(zip(value, args)))


def check_identifier(name: str, key: str) -> None:
    """A cloth's or sphere's name: its USD prim name and the start of its .poly file names, unchanged."""
    if not (_IDENTIFIER.fullmatch(name) and len(name) <= MAX_NAME_LENGTH) or name.casefold() in _DEVICE_NAMES:
        raise SceneError(key, f"a name of at most {MAX_NAME_LENGTH} ASCII letters, digits and '_', not starting "
                              "with a digit (it is the USD prim name as written), nor a Windows device name "
                              "(CON, NUL, COM1, ...)", name)


def check_file_name(name: str, key: str) -> None:
    """A scene's name: the start of its output file names."""
    if not (_FILE_NAME.fullmatch(name) and len(name) <= MAX_NAME_LENGTH) or name.casefold() in _DEVICE_NAMES:
        raise SceneError(key, f"a name of at most {MAX_NAME_LENGTH} ASCII letters, digits, '_' or '-', not "
                              "starting with '-', nor a Windows device name (CON, NUL, COM1, ...): it names the "
                              "output files", name)


def file_name_from(text: str) -> str:
    """A valid scene name made from ``text`` (a file's stem): other characters become '_'."""
    name = re.sub(r"[^A-Za-z0-9_-]", "_", text)[:MAX_NAME_LENGTH]
    name = "_" + name[1:] if name.startswith("-") else name or "scene"
    return name + "_" if name.casefold() in _DEVICE_NAMES else name


def check_float32(derived: float, what: str, key: str, got: object) -> None:
    """A quantity derived from the value ``got`` of ``key`` (``what`` says which) must be a finite, normal
    float32, as the device holds it: ``mass = 1e-39`` has no finite inverse."""
    if not FLOAT32_TINY <= abs(derived) <= FLOAT32_MAX:
        raise SceneError(key, f"a value that keeps {what} a finite, normal float32 (magnitude in "
                              f"[{FLOAT32_TINY:.3g}, {FLOAT32_MAX:.3g}], not {derived:.3g})", got)
