"""The ``upsr`` command line: one module per command group, entry point :func:`main`."""
