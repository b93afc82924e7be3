"""Validation with ``UsdValidation`` (usd-core 26.11 has no usdchecker).

:func:`validate` runs every registered validator (core, UsdGeom, UsdShade,
UsdLux, UsdUtils (USDZ package rules included), ...) on a stage and returns
its findings; a stage *passes* when none is an error.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pxr import Usd, UsdValidation


@dataclass(frozen=True)
class Finding:
    severity: str   # "error", "warn" or "info"
    name: str
    message: str

    def __str__(self) -> str:
        return f"{self.severity}: {self.name}: {self.message}"


_SEVERITY = {
    UsdValidation.ValidationErrorType.Error: "error",
    UsdValidation.ValidationErrorType.Warn: "warn",
    UsdValidation.ValidationErrorType.Info: "info",
}


def validate(stage_or_path: Usd.Stage | str | Path,
             keywords: list[str] | None = None) -> list[Finding]:
    """Findings of every registered validator (or those with ``keywords``)."""
    stage = stage_or_path if isinstance(stage_or_path, Usd.Stage) else Usd.Stage.Open(
        str(stage_or_path))
    if keywords:
        context = UsdValidation.ValidationContext(keywords=list(keywords))
    else:
        registry = UsdValidation.ValidationRegistry()
        context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    found = []
    for err in context.Validate(stage):
        if err.HasNoError():
            continue
        found.append(Finding(_SEVERITY.get(err.GetType(), "error"), err.GetName(),
                             err.GetMessage()))
    return found


def errors(stage_or_path: Usd.Stage | str | Path,
           keywords: list[str] | None = None) -> list[Finding]:
    return [f for f in validate(stage_or_path, keywords) if f.severity == "error"]
