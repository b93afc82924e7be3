"""OpenUSD export: native splats, emissive instancer, UsdLux rig, validation, USDZ.

Importing this package registers the project's codeless schema
(``GaslightProvenanceAPI``) with USD, before anything builds USD's schema
registry where possible.
"""

from .stage import register_schemas

register_schemas()
