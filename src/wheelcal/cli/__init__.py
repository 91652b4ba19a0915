"""Command-line interface: thin parsers over the library (see ``wheelcal --help``)."""
