"""The chip: register table, device model and its engines. Knows no transport and no file.

Imports only go down (docs/architecture.md): nothing here imports ``bus``, ``io``, tools or
commands.
"""
