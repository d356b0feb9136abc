"""Sub-commands of ``bmg160-emu``; one module per command, each with ``register(subparsers)``.

Modules whose name starts with ``_`` are shared helpers, not commands.
"""
