"""Schemas shipped with gaslight2usd: the USD codeless provenance API schema and
the JSON Schemas of the batch manifest and the run report.

Installed as ``gaslight_usd.schemas``; :data:`SCHEMA_DIR` is its folder.
:data:`PLUGIN_DIR` holds the USD plug-in (``plugInfo.json`` +
``generatedSchema.usda``, written from ``schema.usda``) of ``GaslightProvenanceAPI``;
:func:`gaslight_usd.usd.stage.register_schemas` registers it at run time.
"""

from pathlib import Path

SCHEMA_DIR = Path(__file__).resolve().parent
PLUGIN_DIR = SCHEMA_DIR / "gaslight"
PROVENANCE_API = "GaslightProvenanceAPI"
