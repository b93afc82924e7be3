"""Check a JSON document against one of the project's JSON Schemas, with one clear line.

The batch manifest's schema says ``additionalProperties: false``, but nothing
applied it: a typo such as ``"opitons"`` or ``"defualts"`` was ignored and the
scene ran with default options. ``jsonschema`` is a test-only dependency, so
this module checks the subset of JSON Schema (2020-12) the bundled schemas use:
``type``, ``required``, ``properties``, ``additionalProperties`` (false or a
schema), ``propertyNames`` (``enum``), ``items``, ``minItems``, ``maxItems``,
``uniqueItems``, ``enum``, ``pattern``, ``minLength``, ``minimum``,
``exclusiveMinimum`` and local ``$ref``. Problems come as ``where: what``, naming
the closest allowed key for an unknown one; the batch reports them all at once
rather than one per attempt.
"""

from __future__ import annotations

import difflib
import json
import re
from collections.abc import Iterator
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
    return next(iter_problems(document, schema), None)


def iter_problems(document: Any, schema: dict[str, Any], root: dict[str, Any] | None = None,
                  where: str = "(top level)") -> Iterator[str]:
    """Every way ``document`` breaks ``schema``, each as ``"where: what"``.

    ``root`` resolves ``$ref`` when ``schema`` is a part of a larger schema (the
    batch checks each scene against the scene item so that its messages can name
    the scene); a value of the wrong type is one problem, not one per nested key.
    """
    yield from _check(document, schema, schema if root is None else root, where)


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


def _check(value: Any, schema: dict[str, Any], root: dict[str, Any],
           where: str) -> Iterator[str]:
    schema = _resolve(schema, root)
    kind = schema.get("type")
    if kind is not None and not _is_type(value, kind):
        yield f"{where}: expected {kind}, got {type(value).__name__}"
        return
    if "enum" in schema and value not in schema["enum"]:
        yield f"{where}: {value!r} is not one of {', '.join(map(repr, schema['enum']))}"
    if isinstance(value, str) and len(value) < schema.get("minLength", 0):
        yield f"{where}: must not be empty" if schema["minLength"] == 1 else \
            f"{where}: needs at least {schema['minLength']} characters"
    if "pattern" in schema and isinstance(value, str) and not re.search(schema["pattern"],
                                                                         value):
        yield f"{where}: {value!r} does not match {schema['pattern']}"
    if _is_type(value, "number"):
        if "minimum" in schema and value < schema["minimum"]:
            yield f"{where}: {value!r} is below the minimum {schema['minimum']}"
        if "exclusiveMinimum" in schema and value <= schema["exclusiveMinimum"]:
            yield f"{where}: {value!r} must be above {schema['exclusiveMinimum']}"
    if isinstance(value, dict):
        yield from _check_object(value, schema, root, where)
    if isinstance(value, list):
        if len(value) < schema.get("minItems", 0):
            yield f"{where}: needs at least {schema['minItems']} item(s)"
        if len(value) > schema.get("maxItems", len(value)):
            yield f"{where}: takes at most {schema['maxItems']} item(s)"
        if schema.get("uniqueItems") and len({json.dumps(v, sort_keys=True)
                                              for v in value}) < len(value):
            yield f"{where}: items repeat"
        if "items" in schema:
            for i, item in enumerate(value):
                yield from _check(item, schema["items"], root, f"{where}[{i}]")


def _check_object(value: dict, schema: dict[str, Any], root: dict[str, Any],
                  where: str) -> Iterator[str]:
    prefix = "" if where == "(top level)" else f"{where}."
    for key in schema.get("required", []):
        if key not in value:
            yield f"{where}: missing required key {key!r}"
    names = schema.get("propertyNames", {}).get("enum")
    properties = schema.get("properties", {})
    extra = schema.get("additionalProperties", True)
    for key, item in value.items():
        if names is not None and key not in names:
            yield f"{where}: {_unknown_key(key, names)}"
            continue
        if key in properties:
            sub = properties[key]
        elif extra is False:
            yield f"{where}: {_unknown_key(key, list(properties))}"
            continue
        elif isinstance(extra, dict):
            sub = extra
        else:
            continue
        yield from _check(item, sub, root, f"{prefix}{key}")
