"""One module per CLI command, each with ``command`` (a click command) and ``main(argv=None)``."""
