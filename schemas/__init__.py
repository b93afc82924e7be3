"""Schemas shipped with gaslight2usd: the USD codeless provenance API schema and
the JSON Schemas of the batch manifest and the run report.

Installed as ``gaslight_usd.schemas``; :data:`SCHEMA_DIR` is its folder.
"""

from pathlib import Path

SCHEMA_DIR = Path(__file__).resolve().parent
