"""Strict YAML <-> dataclass conversion whose errors name the file, line and key.

Like Drake's ``yaml_load_typed`` (which this follows: the dataclass is the schema, unknown keys are errors,
absent keys keep the dataclass default), but an error says ``rig.yaml:3: key 'arm_lenght' ...`` so a user can
find it, an integer is accepted where a float is expected, a field declared with :func:`documented_field`
``(required=True)`` must be in the file (its default serves Python callers only), and the loaded tree is
validated by the dataclasses' own ``validate`` methods.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
import types
import typing
from pathlib import Path

import yaml

from furuta_drake.errors import ConfigError, read_input_text

YAML12_FLOAT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?")


def documented_field(default, meaning: str, unit: str = "", *, required: bool = False, measure: str = ""):
    """A dataclass field that a YAML file documents: ``meaning`` and ``unit`` name it in errors and templates,
    ``measure`` says how to obtain its value, and a ``required`` field must be in every file (a missing one is a
    ConfigError naming the key, what it is and its unit; the ``default`` then serves Python callers only)."""
    return dataclasses.field(
        default=default, metadata={"meaning": meaning, "unit": unit, "required": required, "measure": measure}
    )


def field_description(field: dataclasses.Field) -> str:
    """ "meaning [unit]" of a :func:`documented_field` ("" for another field)."""
    meaning, unit = field.metadata.get("meaning", ""), field.metadata.get("unit", "")
    return f"{meaning} [{unit}]" if unit else meaning


def load_yaml_dataclass(path: str | Path, schema: type, validate: bool = True):
    """Load ``path`` into an instance of the dataclass ``schema``; raise ConfigError naming file:line:key."""
    text = read_input_text(path, "a YAML file", ConfigError)
    return loads_yaml_dataclass(text, schema, source=str(path), validate=validate)


def loads_yaml_dataclass(text: str, schema: type, source: str = "<string>", validate: bool = True):
    """Like :func:`load_yaml_dataclass` for YAML text; ``source`` names it in errors."""
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{source}{line}: not valid YAML ({getattr(err, 'problem', err)})") from None
    if node is None:
        raise ConfigError(f"{source}: empty YAML file, expected a mapping of {schema.__name__} fields")
    obj = convert_node(node, schema, source, key_path="")
    if validate and hasattr(obj, "validate"):
        try:
            obj.validate()
        except ConfigError as err:
            raise ConfigError(locate(_relative_to_file(str(err), obj.validate), source, key_lines(node))) from None
    return obj


def key_lines(node) -> dict[str, int]:
    """The 1-based line of every key path of a composed YAML tree: ``{"controller": 2, "controller.gain": 3,
    "controller.gain[0]": 3, ...}`` (a mapping entry is at its key's line, a list item at its own)."""
    lines: dict[str, int] = {}

    def walk(node, path: str) -> None:
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                sub_path = f"{path}.{key_node.value}" if path else str(key_node.value)
                lines.setdefault(sub_path, key_node.start_mark.line + 1)
                walk(value_node, sub_path)
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                lines.setdefault(f"{path}[{i}]", item.start_mark.line + 1)
                walk(item, f"{path}[{i}]")

    walk(node, "")
    return lines


def locate(message: str, source: str, lines: dict[str, int]) -> str:
    """``message``, which starts with the key path it is about (as ``validate`` messages do), as
    ``"source:line: message"`` at the line of the longest key path of ``lines`` it starts with; as
    ``"source: message"`` when it starts with none (a key the file leaves at its default)."""

    def starts_with(path: str) -> bool:
        following = message[len(path) : len(path) + 1]
        return message.startswith(path) and not (following.isalnum() or following == "_")

    path = max(filter(starts_with, lines), key=len, default=None)
    return f"{source}:{lines[path]}: {message}" if path is not None else f"{source}: {message}"


def locate_in_file(path: str | Path, err: ConfigError) -> ConfigError:
    """``err``, raised about a config read from the YAML file ``path`` after loading (e.g. a controller gain
    the diagram finds not stabilising), as a ConfigError naming ``path`` and the line of its key."""
    try:
        node = yaml.compose(Path(path).read_text(), Loader=yaml.SafeLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        node = None
    return ConfigError(locate(str(err), str(path), key_lines(node) if node is not None else {}))


def _relative_to_file(message: str, validate) -> str:
    """A ``validate`` message without its default root (``RigParameters.validate`` says "rig.pendulum_mass",
    but a rig file's key is ``pendulum_mass``)."""
    where = inspect.signature(validate).parameters.get("where")
    root = where.default if where is not None and isinstance(where.default, str) else ""
    return message[len(root) + 1 :] if root and message.startswith(f"{root}.") else message


def dump_yaml_dataclass(obj) -> str:
    """YAML text of a dataclass tree (round-trips through :func:`loads_yaml_dataclass`)."""
    return yaml.safe_dump(to_plain(obj), sort_keys=False, default_flow_style=False)


def to_plain(obj):
    """Dataclasses, tuples and numpy scalars to plain dicts, lists and Python numbers."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return obj.item()
    return obj


def _where(source: str, node, key_path: str) -> str:
    line = node.start_mark.line + 1 if node is not None and node.start_mark is not None else None
    key = f" {key_path}" if key_path else ""
    return f"{source}:{line}:{key}" if line is not None else f"{source}:{key}"


def convert_node(node, tp, source: str, key_path: str):
    """A composed YAML node as type ``tp`` (a dataclass, list, dict, Literal, Optional or scalar); errors name
    ``source``, the node's line and ``key_path``."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:null":
            if type(None) in args:
                return None
        non_none = [a for a in args if a is not type(None)]
        if len(non_none) == 1:
            return convert_node(node, non_none[0], source, key_path)
        raise ConfigError(f"{_where(source, node, key_path)} unsupported union type {tp}")
    if dataclasses.is_dataclass(tp):
        return _convert_dataclass(node, tp, source, key_path)
    if origin in (list, tuple):
        if not isinstance(node, yaml.SequenceNode):
            raise ConfigError(f"{_where(source, node, key_path)} expected a list")
        item_tp = args[0] if args else typing.Any
        items = [convert_node(n, item_tp, source, f"{key_path}[{i}]") for i, n in enumerate(node.value)]
        return items if origin is list else tuple(items)
    if origin is dict:
        if not isinstance(node, yaml.MappingNode):
            raise ConfigError(f"{_where(source, node, key_path)} expected a mapping")
        value_tp = args[1] if len(args) == 2 else typing.Any
        return {k.value: convert_node(v, value_tp, source, f"{key_path}.{k.value}") for k, v in node.value}
    if origin is typing.Literal:
        value = _scalar(node, source, key_path)
        if value not in args:
            raise ConfigError(f"{_where(source, node, key_path)} must be one of {list(args)}, got {value!r}")
        return value
    if tp is typing.Any:
        return yaml.safe_load(yaml.serialize(node))
    return _convert_scalar(node, tp, source, key_path)


def _convert_dataclass(node, tp, source: str, key_path: str):
    """A mapping node as the dataclass ``tp``: every key a field, none twice, every required field present."""
    if not isinstance(node, yaml.MappingNode):
        raise ConfigError(f"{_where(source, node, key_path)} expected a mapping of {tp.__name__} fields")
    hints = typing.get_type_hints(tp)
    fields = {f.name for f in dataclasses.fields(tp) if f.init}
    values = {}
    for key_node, value_node in node.value:
        key = key_node.value
        sub_path = f"{key_path}.{key}" if key_path else key
        if key not in fields:
            raise ConfigError(
                f"{_where(source, key_node, sub_path)} unknown key {key!r} in {tp.__name__} "
                f"(known keys: {', '.join(sorted(fields))})"
            )
        if key in values:
            raise ConfigError(f"{_where(source, key_node, sub_path)} duplicate key {key!r}")
        values[key] = convert_node(value_node, hints[key], source, sub_path)
    for field in dataclasses.fields(tp):
        if field.metadata.get("required") and field.name not in values:
            where = f"{_where(source, node, key_path)}:" if key_path else f"{source}:"
            raise ConfigError(f"{where} missing required key {field.name!r} ({field_description(field)})")
    return tp(**values)


def _convert_scalar(node, tp, source: str, key_path: str):
    """A scalar node as ``tp`` (float, int, bool or str), a YAML 1.2 float such as 1e-3 read as a number."""
    value = _scalar(node, source, key_path)
    if tp in (float, int) and isinstance(value, str) and node.style is None and YAML12_FLOAT.fullmatch(value):
        value = float(value)  # 1e-3: a number in YAML 1.2, a string to PyYAML's YAML 1.1 resolver
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{_where(source, node, key_path)} expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{_where(source, node, key_path)} must be finite, got {value!r}")
        return float(value)
    if tp is int:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
            or value != int(value)
        ):
            raise ConfigError(f"{_where(source, node, key_path)} expected an integer, got {value!r}")
        return int(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{_where(source, node, key_path)} expected true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{_where(source, node, key_path)} expected a string, got {value!r}")
        return value
    raise ConfigError(f"{_where(source, node, key_path)} unsupported type {tp}")


def _scalar(node, source: str, key_path: str):
    if not isinstance(node, yaml.ScalarNode):
        raise ConfigError(f"{_where(source, node, key_path)} expected a single value")
    return yaml.safe_load(yaml.serialize(node))
