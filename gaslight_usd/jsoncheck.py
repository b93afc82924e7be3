"""Check a JSON document against one of the project's JSON Schemas, with one clear line.

The batch manifest's schema says ``additionalProperties: false``, but nothing
applied it: a typo such as ``"opitons"`` or ``"defualts"`` was ignored and the
scene ran with default options. ``jsonschema`` is a test-only dependency, so
this module checks the subset of JSON Schema (2020-12) the bundled schemas use:
``type``, ``required``, ``properties``, ``additionalProperties`` (false or a
schema), ``propertyNames`` (``enum``), ``items``, ``minItems``, ``uniqueItems``,
``enum``, ``pattern`` and local ``$ref``. The first problem found is returned
as ``where: what``, naming the closest allowed key for an unknown one.
"""

from __future__ import annotations

import difflib
import json
import re
from importlib.resources import files
from typing import Any

_TYPES: dict[str, tuple[type, ...]] = {
    "object": (dict,), "array": (list,), "string": (str,), "integer": (int,),
    "number": (int, float), "boolean": (bool,), "null": (type(None),),
}


def bundled_schema(name: str) -> dict[str, Any]:
    """A schema shipped in ``gaslight_usd.schemas`` (e.g. ``manifest.schema.json``)."""
    return json.loads(files("gaslight_usd.schemas").joinpath(name).read_text())


def first_problem(document: Any, schema: dict[str, Any]) -> str | None:
    """``"where: what"`` for the first way ``document`` breaks ``schema``, else None."""
    return _check(document, schema, schema, "(top level)")


def _is_type(value: Any, name: str) -> bool:
    if isinstance(value, bool) and name in ("integer", "number"):
        return False
    return isinstance(value, _TYPES[name])


def _resolve(schema: dict[str, Any], root: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        ref = schema["$ref"]
        if not ref.startswith("#/"):
            raise ValueError(f"only local $ref is supported, got {ref!r}")
        node: Any = root
        for part in ref[2:].split("/"):
            node = node[part]
        schema = node
    return schema


def _unknown_key(key: str, allowed: list[str]) -> str:
    close = difflib.get_close_matches(key, allowed, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown key {key!r} (allowed: {', '.join(sorted(allowed))}){hint}"


def _check(value: Any, schema: dict[str, Any], root: dict[str, Any], where: str) -> str | None:
    schema = _resolve(schema, root)
    kind = schema.get("type")
    if kind is not None and not _is_type(value, kind):
        return f"{where}: expected {kind}, got {type(value).__name__}"
    if "enum" in schema and value not in schema["enum"]:
        return f"{where}: {value!r} is not one of {', '.join(map(repr, schema['enum']))}"
    if "pattern" in schema and isinstance(value, str) and not re.search(schema["pattern"],
                                                                         value):
        return f"{where}: {value!r} does not match {schema['pattern']}"
    if isinstance(value, dict):
        return _check_object(value, schema, root, where)
    if isinstance(value, list):
        if len(value) < schema.get("minItems", 0):
            return f"{where}: needs at least {schema['minItems']} item(s)"
        if schema.get("uniqueItems") and len({json.dumps(v, sort_keys=True)
                                              for v in value}) < len(value):
            return f"{where}: items repeat"
        for i, item in enumerate(value):
            if "items" in schema:
                problem = _check(item, schema["items"], root, f"{where}[{i}]")
                if problem:
                    return problem
    return None


def _check_object(value: dict, schema: dict[str, Any], root: dict[str, Any],
                  where: str) -> str | None:
    prefix = "" if where == "(top level)" else f"{where}."
    for key in schema.get("required", []):
        if key not in value:
            return f"{where}: missing required key {key!r}"
    names = schema.get("propertyNames", {}).get("enum")
    properties = schema.get("properties", {})
    extra = schema.get("additionalProperties", True)
    for key, item in value.items():
        if names is not None and key not in names:
            return f"{where}: {_unknown_key(key, names)}"
        if key in properties:
            sub = properties[key]
        elif extra is False:
            return f"{where}: {_unknown_key(key, list(properties))}"
        elif isinstance(extra, dict):
            sub = extra
        else:
            continue
        problem = _check(item, sub, root, f"{prefix}{key}")
        if problem:
            return problem
    return None
