"""The batch manifest: scenes to convert, read from TOML or JSON and checked whole.

A studio's overnight script writes one manifest; a mistake found by the third
scene after two hours of work wastes the night. So the whole manifest is
checked before anything runs, against ``schemas/manifest.schema.json`` and then
for what a schema cannot say (paths that exist, names used once, one way to
give the scale, colour spaces the OCIO config knows), and every problem is
reported at once, each naming its scene and key::

    shots.toml: scene 'hall' (scenes[1]): key 'preset': 'fastest' is not one of ...

``defaults`` holds any scene key but ``name``; a scene's own keys override them
(tables such as ``colour`` and ``options`` merge key by key, lists are replaced).
Relative paths are relative to the manifest. The keys mirror ``gaslight2usd
run``'s options (``preset`` is ``--preset``, ``probes`` is ``--at``, ``targets``
is ``--to``), so a scene of the batch is the same work as that ``run``.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import GaslightError, InputError
from .jsoncheck import bundled_schema, iter_problems
from .kinds import Kind, detect_kind
from .pipeline import DEFAULT_TARGETS, Job

TARGET_NAMES = {"hdr": Kind.HDR_VIEWS, "poses": Kind.POSES, "splats": Kind.SPLATS,
                "usd": Kind.USD, "hdri": Kind.HDRI}
SCALE_KEYS = ("camera_height", "scale", "scale_from")
SCHEMA = "manifest.schema.json"


class ManifestError(InputError):
    """Every problem of a manifest, each naming its scene and key."""

    def __init__(self, path: Path, problems: list[str]):
        super().__init__("; ".join(problems), path)
        self.problems = problems

    def lines(self) -> list[str]:
        """One line per problem, each naming the manifest."""
        return [f"{self.path}: {p}" for p in self.problems]


@dataclass
class Scene:
    """One scene of a batch: its chain job and the manifest entry it came from."""

    name: str
    job: Job
    spec: dict[str, Any] = field(default_factory=dict)
    """The scene's keys with the defaults merged in (paths as written)."""


def read_document(path: Path) -> Any:
    """The manifest as data: TOML for ``.toml``, JSON for ``.json`` (else either)."""
    if not path.is_file():
        raise InputError("no such manifest", path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text (byte {exc.start}): a manifest is TOML or JSON",
                         path) from None
    suffix = path.suffix.lower()
    try:
        if suffix == ".toml":
            return tomllib.loads(text)
        if suffix == ".json":
            return json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        kind = "TOML" if suffix == ".toml" else "JSON"
        raise InputError(f"not valid {kind}: {exc}", path) from None
    for parse in (json.loads, tomllib.loads):
        try:
            return parse(text)
        except (tomllib.TOMLDecodeError, json.JSONDecodeError):
            continue
    raise InputError("neither valid JSON nor TOML (name it .toml or .json for the parser's "
                     "own message)", path)


def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``over`` on top of ``base``: tables merge key by key, anything else is replaced."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def _named(where: str, message: str) -> str:
    """``where: key 'a.b': what`` from the checker's ``a.b: what`` (``(top level): what``
    stays ``where: what``)."""
    key, _, what = message.partition(": ")
    if key == "(top level)":
        return f"{where}: {what}"
    return f"{where}: key '{key}': {what}"


def load_manifest(path: str | Path, out_dir: str | Path) -> list[Scene]:
    """Read and check a manifest; raise :class:`ManifestError` listing every problem.

    Nothing is written. Each scene's job writes into ``out_dir/<name>``.
    """
    path = Path(path)
    data = read_document(path)
    schema = bundled_schema(SCHEMA)
    scenes_schema = schema["properties"]["scenes"]
    shallow = {**schema, "properties": {"defaults": {"type": "object"},
                                        "scenes": {**scenes_schema,
                                                   "items": {"type": "object"}}}}
    problems = list(iter_problems(data, shallow))
    if problems:  # no scenes list to look into
        raise ManifestError(path, problems)
    defaults = data.get("defaults", {})
    problems += [_named("defaults", p) for p in
                 iter_problems(defaults, schema["properties"]["defaults"], schema)]
    seen: dict[str, int] = {}
    scenes: list[Scene] = []
    for i, entry in enumerate(data["scenes"]):
        name = entry.get("name")
        named = isinstance(name, str) and bool(name)
        where = f"scene {name!r} (scenes[{i}])" if named else f"scenes[{i}]"
        found = [_named(where, p) for p in iter_problems(entry, scenes_schema["items"], schema)]
        if named and name in seen:
            found.append(f"{where}: key 'name': {name!r} is used twice "
                         f"(also scenes[{seen[name]}])")
        elif named:
            seen[name] = i
        if found:
            problems += found
            continue
        spec = merge(defaults, entry)
        scene, found = _scene(spec, where, path.parent, Path(out_dir))
        problems += found
        if scene is not None:
            scenes.append(scene)
    if problems:
        raise ManifestError(path, problems)
    return scenes


def _scene(spec: dict[str, Any], where: str, base: Path,
           out_dir: Path) -> tuple[Scene | None, list[str]]:
    """A scene's job from its merged keys, with what a schema cannot check."""
    problems: list[str] = []

    def resolved(key: str, text: str) -> Path:
        p = (base / text).resolve()
        if not p.exists():
            problems.append(f"{where}: key '{key}': no such file or folder: {p}")
        return p

    inputs = [resolved(f"inputs[{i}]", t) for i, t in enumerate(spec.get("inputs", []))]
    if "photos" in spec:
        inputs.insert(0, resolved("photos", spec["photos"]))
    if "poses" in spec:
        poses = resolved("poses", spec["poses"])
        if poses.exists():
            try:
                kind = detect_kind(poses)
            except GaslightError:
                kind = None
            if kind is not Kind.POSES:
                problems.append(f"{where}: key 'poses': not a COLMAP model or "
                                f"transforms.json: {poses}")
        inputs.append(poses)
    if not inputs:
        problems.append(f"{where}: needs 'photos' or 'inputs' (here or in defaults)")
    scale = [k for k in SCALE_KEYS if k in spec]
    if len(scale) > 1:
        problems.append(f"{where}: keys {' and '.join(map(repr, scale))} both give the "
                        "scale; keep one")
    colour = dict(spec.get("colour", {}))
    if "config" in colour and "://" not in colour["config"]:  # a file: beside the manifest
        colour["config"] = str(resolved("colour.config", colour["config"]))
    if not any("'colour.config'" in p for p in problems):
        problems += _colour_problems(colour, where)
    choose = dict(spec.get("choose", {}))
    if "method" in spec:
        choose["uplift"] = f"uplift.{spec['method']}"
    problems += _converter_problems(choose, where)
    if problems:
        return None, problems
    options: dict[str, dict[str, Any]] = {k: dict(v) for k, v in
                                          spec.get("options", {}).items()}
    if "preset" in spec:
        options.setdefault("fit", {})["preset"] = spec["preset"]
    if "probes" in spec:
        options.setdefault("hdri", {})["at"] = [list(map(float, p)) for p in spec["probes"]]
    if "output_space" in colour:
        options.setdefault("hdri", {})["output_space"] = colour["output_space"]
    for key in scale:
        options.setdefault("poses", {})[key] = spec[key]
    settings = {"ocio_config": colour.get("config"), "input_space": colour.get("input_space"),
                "working_space": colour.get("working_space"), "device": spec.get("device"),
                "seed": spec.get("seed")}
    targets = spec.get("targets")
    job = Job(inputs=inputs, out_dir=out_dir / spec["name"],
              targets=tuple(TARGET_NAMES[t] for t in targets) if targets else DEFAULT_TARGETS,
              choose=choose, options=options,
              settings={k: v for k, v in settings.items() if v is not None})
    return Scene(spec["name"], job, spec), []


_CONFIGS: dict[str | None, str] = {}


def _colour_problems(colour: dict[str, str], where: str) -> list[str]:
    """Unknown OCIO configs or space names, each naming its key (configs load once)."""
    from . import colour as ocio

    config = colour.get("config")
    try:
        if config not in _CONFIGS:
            uri = ocio.resolve_config_uri(config)
            ocio.load_config(uri)
            _CONFIGS[config] = uri
    except GaslightError as exc:
        return [f"{where}: key 'colour.config': {exc.message}"]
    problems = []
    for key in ("input_space", "working_space", "output_space"):
        if key in colour:
            try:
                ocio.resolve_space(colour[key], _CONFIGS[config])
            except GaslightError as exc:
                problems.append(f"{where}: key 'colour.{key}': {exc.message}")
    return problems


def _converter_problems(choose: dict[str, str], where: str) -> list[str]:
    from .registry import default_registry

    registry = default_registry()
    return [f"{where}: key 'choose.{step}': no converter {name!r} is installed"
            for step, name in choose.items() if name not in registry]
