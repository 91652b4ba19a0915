"""Command-line interface: thin parsers over the library (see ``wheelcal --help``).

Layer 9, the top (above ``batch`` and ``study``, beside ``api``).
"""
