"""Built-in converters: one module per step implementation.

Each module exposes ``CONVERTERS``, a list of
:class:`gaslight_usd.registry.Converter`. The engine discovers them; nothing
here is imported by name. This package installs as ``gaslight_usd.converters``.
"""
