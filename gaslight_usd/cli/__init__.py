"""The ``gaslight2usd`` command line: one module per subcommand."""
