"""The converter registry: every arrow of the chain is a named converter.

This module is the whole converter contract: what a converter is given
(:class:`StageContext` with the run's :class:`Settings`), what it returns
(:class:`StageResult`) and how it is found. The chain runner depends on it,
never the other way round.

Built-in converters live in the ``gaslight_usd.converters`` package, one module
per step implementation; each module exposes ``CONVERTERS`` (a list of
:class:`Converter`). Third parties add theirs through the entry-point group
``gaslight_usd.converters``: each entry point names a :class:`Converter`, a
list of them, or a callable returning either. The engine imports no converter
by name.
"""

from __future__ import annotations

import importlib
import logging
import pkgutil
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

from . import colour
from .errors import UsageError
from .kinds import Artifact, Kind
from .progress import Progress

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "gaslight_usd.converters"
BUILTIN_PACKAGE = "gaslight_usd.converters"


@dataclass
class Settings:
    """Run-wide settings every converter may read."""

    ocio_config: str = colour.BUILTIN_CONFIG
    input_space: str = colour.DEFAULT_INPUT_SPACE
    working_space: str = colour.DEFAULT_WORKING_SPACE
    device: str = "cpu"
    seed: int = 0

    @classmethod
    def resolved(cls, ocio_config: str | None = None, input_space: str | None = None,
                 working_space: str | None = None, **kw: Any) -> Settings:
        """Settings with the OCIO config resolved and the space names checked."""
        uri = colour.resolve_config_uri(ocio_config)
        return cls(
            ocio_config=uri,
            input_space=colour.resolve_space(input_space or colour.DEFAULT_INPUT_SPACE, uri),
            working_space=colour.resolve_space(
                working_space or colour.DEFAULT_WORKING_SPACE, uri),
            **kw,
        )


@dataclass
class StageContext:
    """What a converter is given: its inputs, where to write, the run's settings and
    its step's options (a dict; :func:`options_from` types it)."""

    inputs: dict[Kind, Artifact]
    output: Path
    settings: Settings
    options: dict[str, Any]
    progress: Progress
    resume: bool = False
    """Whether the run resumes: a stage may continue its own interrupted work
    (the fit from its checkpoint) instead of starting over."""

    def input(self, kind: Kind) -> Artifact:
        return self.inputs[kind]


@dataclass
class StageResult:
    """What a converter returns: facts about its output (``metadata``, travels with the
    artifact), ``counts`` and ``metrics`` (both written to report.json)."""

    metadata: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Converter:
    """One step of the chain: typed inputs -> one output kind.

    ``run(ctx)`` reads ``ctx.inputs``, writes ``ctx.output`` (atomically) and
    returns a :class:`StageResult`. ``method`` groups
    alternative implementations of one step (e.g. ``uplift``: ``bracket``,
    ``recursive``); ``priority`` orders them when the user names none.
    """

    name: str
    inputs: tuple[Kind, ...]
    output: Kind
    run: Callable[[StageContext], StageResult]
    description: str
    step: str
    priority: int = 0
    accepts: Callable[[dict[Kind, Any]], str | None] | None = None
    """Optional check of the actual inputs before running: ``None`` when this
    converter applies, else the reason it does not (e.g. "no brackets"). When
    the user named no converter for the step, the runner then falls back to
    the next one for the same step."""
    options: type | None = None
    """The dataclass of this converter's options (its defaults are the defaults);
    ``run`` builds it with :func:`options_from`. None: a plug-in that takes any."""

    def refusal(self, inputs: dict[Kind, Any]) -> str | None:
        return self.accepts(inputs) if self.accepts else None


T = TypeVar("T")


def option_key(f: Any) -> str:
    """The options-dict key of a dataclass field: its ``key`` metadata, else its name
    (``as`` is a Python keyword, so the USD forms field is ``forms`` with key ``as``)."""
    return f.metadata.get("key", f.name)


def option_names(options: type) -> set[str]:
    """The keys an options dataclass takes."""
    return {option_key(f) for f in fields(options)}


def options_from(options: type[T], given: Mapping[str, Any]) -> T:
    """``options`` built from a step's options dict: None values keep the default.

    Keys the dataclass does not have are left out: they belong to another converter
    of the same step (the chain has refused keys no converter of the step takes,
    :meth:`Registry.check_options`).
    """
    return options(**{f.name: given[option_key(f)] for f in fields(options)
                      if given.get(option_key(f)) is not None})


class Registry:
    def __init__(self, converters: Iterable[Converter] = ()):
        self._by_name: dict[str, Converter] = {}
        for conv in converters:
            self.add(conv)

    def add(self, conv: Converter) -> None:
        if conv.name in self._by_name:
            raise ValueError(f"converter {conv.name!r} is registered twice")
        self._by_name[conv.name] = conv

    def __contains__(self, name: str) -> bool:
        return name in self._by_name

    def __getitem__(self, name: str) -> Converter:
        return self._by_name[name]

    def __iter__(self):
        return iter(sorted(self._by_name.values(), key=lambda c: (c.step, -c.priority, c.name)))

    def __len__(self) -> int:
        return len(self._by_name)

    def alternatives(self, conv: Converter) -> list[Converter]:
        """Converters of the same step, inputs and output as ``conv``, preferred first."""
        return [c for c in self.producing(conv.output)
                if c.step == conv.step and set(c.inputs) == set(conv.inputs)]

    def check_options(self, step: str, given: Mapping[str, Any]) -> None:
        """Raise :class:`UsageError` naming the options no converter of ``step`` takes.

        A step's options go to whichever of its converters runs (``auto`` may fall
        back to another), so a key is known when one of them takes it; a step with a
        converter that declares no options (a plug-in) takes anything.
        """
        convs = [c for c in self._by_name.values() if c.step == step]
        if not convs or any(c.options is None for c in convs):
            return
        known = set().union(*(option_names(c.options) for c in convs))
        unknown = sorted(set(given) - known)
        if unknown:
            raise UsageError(f"unknown {step} option(s): {', '.join(unknown)} "
                             f"(known: {', '.join(sorted(known))})")

    def producing(self, kind: Kind) -> list[Converter]:
        """Converters that output ``kind``, preferred first."""
        return sorted((c for c in self._by_name.values() if c.output == kind),
                      key=lambda c: (-c.priority, c.name))


def _as_converters(obj: Any) -> list[Converter]:
    if callable(obj) and not isinstance(obj, Converter):
        obj = obj()
    if isinstance(obj, Converter):
        return [obj]
    return [c for c in obj if isinstance(c, Converter)]


def _builtin_converters() -> list[Converter]:
    package = importlib.import_module(BUILTIN_PACKAGE)
    found: list[Converter] = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{BUILTIN_PACKAGE}.{info.name}")
        found.extend(getattr(module, "CONVERTERS", []))
    return found


def _plugin_converters() -> list[Converter]:
    found: list[Converter] = []
    from importlib.metadata import entry_points  # only when plug-ins are looked up

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            found.extend(_as_converters(ep.load()))
        except Exception as exc:  # a broken plug-in must not break the tool
            log.warning("converter plug-in %s failed to load: %s", ep.name, exc)
    return found


_default: Registry | None = None


def default_registry() -> Registry:
    """Built-ins plus entry-point plug-ins, loaded once."""
    global _default
    if _default is None:
        _default = Registry(_builtin_converters() + _plugin_converters())
    return _default
